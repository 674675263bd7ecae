//! The library's structure, checked on every test run (docs/architecture.md):
//! - every import points down the layers (foundation, stages, estimation, pipeline);
//! - no import circles between the library's files;
//! - the program uses the library's public interface only and stays thin;
//! - no library file holds more than 1,000 lines before its tests, and the estimator's
//!   `calib/mod.rs` only declares and wires its stages (at most 400 lines of code);
//! - YAML is read and written only in `io`; there is one camera model.
//!
//! Imports are read from the source text: `crate::a::b` paths (in `use` lines or written out),
//! `super::` paths, and a module's own references to its child modules (`child::item`). Test
//! code (`#[cfg(test)]` items) is left out: tests may use anything.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Layer of each top-level module; a module may import only from lower layers, or from its own
/// top-level module.
fn layer(top: &str) -> Option<u32> {
    Some(match top {
        "error" | "time" => 0,
        "files" => 1,
        "lie" | "parallel" | "rng" => 1,
        "types" => 2,
        "io" | "trajectory" => 3,
        "vision" | "calib" => 4,
        "camcal" | "sim" => 5,
        "eval" | "report" => 6,
        "pipeline" => 7,
        "" => 8, // the crate root re-exports
        _ => return None,
    })
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a library file: `src/calib/mod.rs` is `calib`, `src/calib/samples.rs` is
/// `calib::samples`, `src/lib.rs` is the root (empty). Files included with `#[path]` from test
/// modules have names ending in `_tests.rs` and are skipped.
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let mut parts: Vec<String> = rel
        .with_extension("")
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect();
    if parts.first().is_some_and(|p| p == "bin") {
        return None;
    }
    if parts.last().is_some_and(|p| p.ends_with("_tests")) {
        return None;
    }
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    Some(parts.join("::"))
}

/// The text of a file without comments and without `#[cfg(test)]` items.
fn code_without_tests(text: &str) -> String {
    let lines: Vec<&str> = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect();
    let mut out = String::new();
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim() == "#[cfg(test)]" {
            // Skip the attributes and the item that follows: a `mod x;` line, or a block up to
            // its matching closing brace.
            let mut depth = 0i32;
            let mut opened = false;
            i += 1;
            while i < lines.len() {
                let l = lines[i];
                for ch in l.chars() {
                    match ch {
                        '{' => {
                            depth += 1;
                            opened = true;
                        }
                        '}' => depth -= 1,
                        _ => {}
                    }
                }
                i += 1;
                if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                    break;
                }
            }
            continue;
        }
        out.push_str(lines[i]);
        out.push('\n');
        i += 1;
    }
    out
}

/// Identifier paths that follow `prefix` (`crate::`, `super::`), with `{a, b::c}` groups
/// expanded one level.
fn paths_after(code: &str, prefix: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    let mut start = 0;
    while let Some(pos) = code[start..].find(prefix) {
        let at = start + pos;
        start = at + prefix.len();
        if at > 0 {
            let c = bytes[at - 1] as char;
            if c.is_alphanumeric() || c == '_' || c == ':' {
                continue;
            }
        }
        let rest = &code[at + prefix.len()..];
        let end = rest
            .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
            .unwrap_or(rest.len());
        let head = rest[..end].trim_end_matches(':');
        let base: Vec<String> = head
            .split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        let after = &rest[end..];
        if (end == 0 || rest[..end].ends_with("::")) && after.starts_with('{') {
            let close = after.find('}').unwrap_or(after.len());
            for item in after[1..close].split(',') {
                let item = item.split(" as ").next().unwrap_or("").trim();
                if item.is_empty() || item == "self" {
                    out.push(base.clone());
                    continue;
                }
                let mut p = base.clone();
                p.extend(item.split("::").map(|s| s.trim().to_string()));
                out.push(p);
            }
        }
        out.push(base);
    }
    out
}

struct Graph {
    /// Module -> modules it imports from.
    edges: BTreeMap<String, BTreeSet<String>>,
}

fn library_graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut code = BTreeMap::new();
    for f in &files {
        if let Some(m) = module_of(&src, f) {
            let text =
                std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            code.insert(m, code_without_tests(&text));
        }
    }
    let modules: BTreeSet<String> = code.keys().cloned().collect();
    // The longest prefix of `path` that names a module.
    let resolve = |path: &[String]| -> Option<String> {
        (1..=path.len())
            .rev()
            .map(|k| path[..k].join("::"))
            .find(|m| modules.contains(m))
    };
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, text) in &code {
        let e = edges.entry(m.clone()).or_default();
        let parent: Vec<String> = if m.is_empty() {
            Vec::new()
        } else {
            let mut p: Vec<String> = m.split("::").map(String::from).collect();
            p.pop();
            p
        };
        for p in paths_after(text, "crate::") {
            match resolve(&p) {
                Some(t) => {
                    e.insert(t);
                }
                // `crate::Error`, `crate::{Error, Result}`: an item re-exported by the crate
                // root, reached through the top.
                None if !p.is_empty() => {
                    e.insert(String::new());
                }
                None => {}
            }
        }
        for p in paths_after(text, "super::") {
            let mut full = parent.clone();
            full.extend(p);
            if let Some(t) = resolve(&full) {
                e.insert(t);
            }
        }
        // References to the module's own children (`child::item`, `pub use child::X`).
        let own: Vec<String> = if m.is_empty() {
            Vec::new()
        } else {
            m.split("::").map(String::from).collect()
        };
        for child in modules.iter().filter(|c| {
            let depth = if m.is_empty() { 0 } else { own.len() };
            let parts: Vec<&str> = c.split("::").collect();
            parts.len() == depth + 1 && (m.is_empty() || c.starts_with(&format!("{m}::")))
        }) {
            let name = child.rsplit("::").next().unwrap_or(child);
            if !paths_after(text, &format!("{name}::")).is_empty() {
                e.insert(child.clone());
            }
        }
        e.remove(m);
    }
    Graph { edges }
}

fn top(m: &str) -> &str {
    m.split("::").next().unwrap_or("")
}

#[test]
fn imports_point_down_the_layers() {
    let g = library_graph();
    let mut wrong = Vec::new();
    for (a, targets) in &g.edges {
        let la = layer(top(a)).unwrap_or_else(|| panic!("module {a} has no layer in this test"));
        for b in targets {
            if top(a) == top(b) {
                continue;
            }
            let lb = layer(top(b)).unwrap_or_else(|| panic!("module {b} has no layer"));
            // Within the foundation, lower layers first; elsewhere strictly downwards.
            if lb >= la {
                wrong.push(format!("{a} (layer {la}) imports {b} (layer {lb})"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the layers:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_import_circles_between_files() {
    let g = library_graph();
    // Tarjan's strongly connected components.
    struct State<'a> {
        g: &'a Graph,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        next: usize,
        circles: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        s.index.insert(v, s.next);
        s.low.insert(v, s.next);
        s.next += 1;
        s.stack.push(v);
        s.on.insert(v);
        if let Some(ws) = s.g.edges.get(v) {
            for w in ws {
                let w = w.as_str();
                if !s.index.contains_key(w) {
                    visit(s, w);
                    let lw = s.low[w];
                    let lv = s.low[v];
                    s.low.insert(v, lv.min(lw));
                } else if s.on.contains(w) {
                    let iw = s.index[w];
                    let lv = s.low[v];
                    s.low.insert(v, lv.min(iw));
                }
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.circles.push(comp);
            }
        }
    }
    let mut s = State {
        g: &g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        circles: Vec::new(),
    };
    for v in g.edges.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    // The crate root declares every module and re-exports entry points; it is the top, not a
    // member of a circle.
    let circles: Vec<_> = s
        .circles
        .into_iter()
        .filter(|c| !(c.len() == 2 && c.iter().any(|m| m.is_empty())))
        .collect();
    assert!(circles.is_empty(), "import circles: {circles:?}");
}

#[test]
fn the_checker_sees_imports_and_circles() {
    // The parsing above is what the two tests rely on: check it on known text.
    let code = "use crate::io::dvl::{DvlLog, read_dvl_log};\nuse super::model::{self, NPARAM};\n\
                let x = crate::lie::so3::exp(&v);\n#[cfg(test)]\nmod tests {\n use crate::rng::Rng;\n}\n";
    let stripped = code_without_tests(code);
    assert!(!stripped.contains("rng::Rng"));
    let p = paths_after(&stripped, "crate::");
    assert!(p.contains(&vec!["io".into(), "dvl".into(), "read_dvl_log".into()]));
    assert!(p.contains(&vec!["lie".into(), "so3".into(), "exp".into()]));
    let s = paths_after(&stripped, "super::");
    assert!(s.contains(&vec!["model".into(), "NPARAM".into()]));
    // The real graph has the edges it must have.
    let g = library_graph();
    assert!(
        g.edges["calib::cosensor"].contains("trajectory"),
        "{:?}",
        g.edges["calib::cosensor"]
    );
    assert!(g.edges["calib::joint::factors"].contains("trajectory::solver"));
    assert!(g.edges["calib::joint::factors"].contains("calib::joint::problem"));
    assert!(g.edges["pipeline::calibration"].contains("calib"));
}

#[test]
fn the_program_is_thin_and_uses_the_public_interface() {
    let bin = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/bin/dvlcal");
    let mut files = Vec::new();
    rust_files(&bin, &mut files);
    // Files of test-only modules (`#[cfg(test)] mod rules;`) check the program; they are not
    // part of it.
    let mut test_modules = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let lines: Vec<&str> = text.lines().map(str::trim).collect();
        for w in lines.windows(2) {
            if let (["#[cfg(test)]", item], Some(name)) = (w, w[1].strip_prefix("mod ")) {
                if item.ends_with(';') {
                    test_modules.push(bin.join(format!("{}.rs", name.trim_end_matches(';'))));
                }
            }
        }
    }
    let mut lines = 0;
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        if !test_modules.contains(f) {
            lines += text.lines().count();
        }
        // The program reaches the library only through `dvlcal::`; internal stages stay out.
        for internal in [
            "calib::joint",
            "calib::update",
            "trajectory::solver",
            "trajectory::blocktri",
        ] {
            assert!(
                !text.contains(internal),
                "{} uses the library internal {internal}",
                f.display()
            );
        }
    }
    // The program parses arguments, calls the pipeline and prints: it was 2368 lines when it
    // still did the library's work. A new command adds its argument struct, not an estimator:
    // about 100 lines per command (16 commands, `watch` the latest: its loop, the Ctrl-C flag,
    // its targets and the standard output kept for its JSON while the final calibration
    // prints), and a
    // few per flag (`--clock-drift` the latest), and the flags given on the command line
    // handed to the library's checks of options a run would not use (`pipeline::unused`), with
    // the image-only bag options of `detect` and `calibrate-cameras`.
    assert!(lines < 1985, "src/bin/dvlcal has {lines} lines");
}

/// Every library file with its path relative to `src/` and its text.
fn library_files() -> Vec<(String, String)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files
        .iter()
        .filter(|f| !f.starts_with(src.join("bin")))
        .map(|f| {
            let rel = f
                .strip_prefix(&src)
                .unwrap_or(f)
                .to_string_lossy()
                .into_owned();
            let text =
                std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            (rel, text)
        })
        .collect()
}

/// The lines of a file before its tests: up to the `#[cfg(test)]` line of its first test
/// module (not one on a test-only function), comments included.
fn lines_before_tests(text: &str) -> usize {
    let lines: Vec<&str> = text.lines().collect();
    lines
        .iter()
        .enumerate()
        .position(|(i, l)| l.trim() == "#[cfg(test)]" && opens_a_module(&lines[i + 1..]))
        .unwrap_or(lines.len())
}

/// Whether the item after an attribute (`rest` its following lines, doc comments and further
/// attributes skipped) is a module.
fn opens_a_module(rest: &[&str]) -> bool {
    rest.iter()
        .map(|l| l.trim())
        .find(|l| !l.starts_with("#[") && !l.starts_with("///"))
        .is_some_and(|l| {
            l.starts_with("mod ") || l.starts_with("pub mod ") || l.starts_with("pub(crate) mod ")
        })
}

/// The lines of code before a file's tests: without blank lines and comments.
fn code_lines_before_tests(text: &str) -> usize {
    text.lines()
        .take(lines_before_tests(text))
        .filter(|l| {
            let t = l.trim();
            !t.is_empty() && !t.starts_with("//")
        })
        .count()
}

#[test]
fn no_file_is_a_room_of_its_own() {
    let long: Vec<String> = library_files()
        .iter()
        .map(|(f, text)| (f, lines_before_tests(text)))
        .filter(|&(_, n)| n > 1000)
        .map(|(f, n)| format!("{f}: {n} lines before its tests"))
        .collect();
    assert!(
        long.is_empty(),
        "files over 1,000 lines:\n{}",
        long.join("\n")
    );
    // The estimator's module declares and wires its stages; the stages live in files of their
    // own.
    let files = library_files();
    let (_, calib) = files
        .iter()
        .find(|(f, _)| f == "calib/mod.rs")
        .expect("src/calib/mod.rs");
    let n = code_lines_before_tests(calib);
    assert!(n <= 400, "calib/mod.rs has {n} lines of code");
}

#[test]
fn yaml_is_read_and_written_only_in_io() {
    let outside: Vec<String> = library_files()
        .into_iter()
        .filter(|(f, text)| {
            !f.starts_with("io/") && code_without_tests(text).contains("serde_yaml")
        })
        .map(|(f, _)| f)
        .collect();
    assert!(outside.is_empty(), "YAML handled outside io: {outside:?}");
}

#[test]
fn there_is_one_camera_model() {
    // A camera model is a type with the radial-tangential distortion among its cases; a second
    // one (a twin decoded from another format and converted) is what this rules out.
    let mut models = Vec::new();
    for (f, text) in library_files() {
        let code = code_without_tests(&text);
        let lines: Vec<&str> = code.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            let t = l.trim_start();
            if !(t.starts_with("pub enum ") || t.starts_with("enum ") || t.contains(" enum ")) {
                continue;
            }
            // The enum's body, up to its closing brace at the same indentation.
            let indent = l.len() - t.len();
            let body = lines[i + 1..]
                .iter()
                .take_while(|b| !(b.len() > indent && b[indent..].starts_with('}')))
                .any(|b| b.trim_start().starts_with("RadTan"));
            if body {
                models.push(format!("{f}: {}", t.trim_end_matches('{').trim()));
            }
        }
    }
    assert_eq!(models.len(), 1, "camera models: {models:?}");
}

#[test]
fn the_checker_sees_the_crate_roots_reexports() {
    let code = "use crate::{Error, Result};\nlet e = crate::Error::Input(s);\n";
    let p = paths_after(code, "crate::");
    assert!(p.contains(&vec!["Error".to_string()]), "{p:?}");
    assert!(p.contains(&vec!["Result".to_string()]), "{p:?}");
    assert!(
        p.contains(&vec!["Error".to_string(), "Input".to_string()]),
        "{p:?}"
    );
    // No library file reaches the root that way (imports_point_down_the_layers would name it).
    let g = library_graph();
    let via_root: Vec<&String> = g
        .edges
        .iter()
        .filter(|(m, t)| !m.is_empty() && t.contains(""))
        .map(|(m, _)| m)
        .collect();
    assert!(via_root.is_empty(), "{via_root:?}");
}
