//! Folders of calibration images, paired across the cameras of a chain by time stamp (and the
//! pairing of any time-stamped image lists, a bag's image topics' too: [`pair_frames`]).
//!
//! Two layouts are read:
//! - kalibr_bagcreater's: `DIR/cam0/<t_ns>.png` (or `.jpg`, `.jpeg`, `.pgm`), `DIR/cam1/...`;
//! - EuRoC's: `DIR/mav0/camN/data.csv` (`#timestamp [ns],filename`) with the images in
//!   `DIR/mav0/camN/data/`; `DIR` may also be the `mav0` folder itself.
//!
//! Time stamps are on the camera clock: integer nanoseconds (both layouts' convention), or
//! decimal seconds (`1700000000.050000.png`). Integer names in milliseconds or microseconds are
//! recognised (as Unix times at a camera's frame rate) and read as such, with a warning. A
//! frame is one cam0 image with, for
//! every other camera, the image closest in time within the tolerance (each image used at most
//! once). cam0 images without a partner are kept as frames with a missing image (their pose comes
//! from cam0 alone); images of the other cameras without a cam0 partner are dropped. Both are
//! counted.
//!
//! Missing folders: no cam0 images is an error; a chain of several cameras whose cam1 (or later)
//! folder is missing or empty falls back to the cameras that have images, with a warning in
//! [`ScanStats::warnings`] naming the cameras the poses come from. Camera folders beyond the
//! chain's cameras that hold images (a camchain of cam0 alone beside a full `cam1/`) are not
//! used, with a warning that counts their images.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Where one image is: a file, or a message of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ImageRef {
    /// An image file (PNG, JPEG, PGM).
    File(PathBuf),
    /// An image message of a bag: its topic and its 1-based number among that topic's
    /// messages.
    Message {
        /// The topic.
        topic: String,
        /// The message's number on the topic.
        index: u64,
    },
}

impl ImageRef {
    /// The file, for an image file.
    pub fn path(&self) -> Option<&Path> {
        match self {
            ImageRef::File(p) => Some(p),
            ImageRef::Message { .. } => None,
        }
    }

    /// A short name: the file name, or `topic#index`.
    pub fn short_name(&self) -> String {
        match self {
            ImageRef::File(p) => crate::files::file_name_of(p),
            ImageRef::Message { topic, index } => format!("{topic}#{index}"),
        }
    }
}

impl std::fmt::Display for ImageRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImageRef::File(p) => write!(f, "{}", p.display()),
            ImageRef::Message { topic, index } => write!(f, "{topic} message {index}"),
        }
    }
}

/// One time instant: one image per camera (`None` where that camera has no image).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StereoFrame {
    /// cam0's time stamp, integer nanoseconds.
    pub t_ns: i64,
    /// The image of each camera, indexed by camera (`None`: no image from that camera).
    pub images: Vec<Option<ImageRef>>,
}

/// Which layout a folder was read as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// `DIR/camN/<t_ns>.png`.
    Kalibr,
    /// `mav0/camN/data.csv` + `data/`.
    Euroc,
    /// Image topics of a bag.
    Bag,
}

/// What [`scan_images`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanStats {
    /// The layout the folder was read as.
    pub layout: Layout,
    /// The folder of each camera's images (`None`: missing).
    pub folders: Vec<Option<PathBuf>>,
    /// Images listed per camera.
    pub images: Vec<usize>,
    /// Frames with an image from every camera.
    pub complete: usize,
    /// cam0 images without a partner in some other camera (kept, mono).
    pub unpaired_cam0: usize,
    /// Images of the other cameras without a cam0 partner (dropped).
    pub unpaired_other: usize,
    /// Files whose name is not `<integer ns>.<image extension>` (ignored), and EuRoC CSV lines
    /// that could not be read.
    pub ignored: usize,
    /// Images whose time stamp repeats one already seen in the same camera (dropped).
    pub duplicates: usize,
    /// Things the user should know (a missing camera folder, ...).
    pub warnings: Vec<String>,
}

const EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "pgm", "pnm"];

/// The number of cameras whose images a folder holds: `cam0`, `cam1`, ... (either layout),
/// counted up to the first missing one.
pub fn camera_count(dir: &Path) -> usize {
    let root = if dir.join("mav0").join("cam0").is_dir() {
        dir.join("mav0")
    } else {
        dir.to_path_buf()
    };
    (0..)
        .take_while(|c| root.join(format!("cam{c}")).is_dir())
        .count()
}

/// Lists and pairs the images of `cams` cameras under `dir` (see the module documentation).
/// `tolerance_ns`: largest time difference between paired images.
pub fn scan_images(
    dir: &Path,
    cams: usize,
    tolerance_ns: i64,
) -> Result<(Vec<StereoFrame>, ScanStats)> {
    if cams == 0 {
        return Err(Error::Input("scan_images: no cameras".into()));
    }
    if !dir.is_dir() {
        return Err(Error::Input(format!("{}: not a folder", dir.display())));
    }
    let euroc_root = if dir.join("mav0").join("cam0").join("data.csv").is_file() {
        Some(dir.join("mav0"))
    } else if dir.join("cam0").join("data.csv").is_file() {
        Some(dir.to_path_buf())
    } else {
        None
    };
    let layout = if euroc_root.is_some() {
        Layout::Euroc
    } else {
        Layout::Kalibr
    };
    let mut stats = ScanStats {
        layout,
        folders: Vec::new(),
        images: Vec::new(),
        complete: 0,
        unpaired_cam0: 0,
        unpaired_other: 0,
        ignored: 0,
        duplicates: 0,
        warnings: Vec::new(),
    };
    let mut lists: Vec<Vec<(i64, PathBuf)>> = Vec::new();
    for c in 0..cams {
        let name = format!("cam{c}");
        let (folder, list) = match &euroc_root {
            Some(root) => {
                let folder = root.join(&name);
                let csv = folder.join("data.csv");
                if csv.is_file() {
                    let l = read_euroc_csv(&csv, &folder.join("data"), &mut stats.ignored)?;
                    (Some(folder), l)
                } else {
                    (None, Vec::new())
                }
            }
            None => {
                let folder = dir.join(&name);
                if folder.is_dir() {
                    let l = list_folder(&folder, &mut stats.ignored)?;
                    (Some(folder), l)
                } else {
                    (None, Vec::new())
                }
            }
        };
        let label = folder
            .as_ref()
            .map_or_else(|| name.clone(), |f| f.display().to_string());
        let mut list = to_nanos(list, &label, &mut stats.ignored, &mut stats.warnings);
        list.sort();
        let before = list.len();
        list.dedup_by_key(|e| e.0);
        stats.duplicates += before - list.len();
        stats.images.push(list.len());
        stats.folders.push(folder);
        lists.push(list);
    }
    if lists[0].is_empty() {
        let what = match (&stats.folders[0], layout) {
            (None, Layout::Kalibr) => format!(
                "{}: no cam0 folder (expected DIR/cam0/<t_ns>.png or DIR/mav0/cam0/data.csv)",
                dir.display()
            ),
            (Some(f), _) => format!("{}: no cam0 images", f.display()),
            (None, Layout::Euroc | Layout::Bag) => format!("{}: no cam0 images", dir.display()),
        };
        return Err(Error::Input(what));
    }
    let labels: Vec<String> = (0..cams)
        .map(|c| match &stats.folders[c] {
            None => format!("{}: no cam{c} folder", dir.display()),
            Some(f) => format!("{}: no images", f.display()),
        })
        .collect();
    let lists = lists
        .into_iter()
        .map(|l| l.into_iter().map(|(t, p)| (t, ImageRef::File(p))).collect())
        .collect();
    let frames = pair_frames(lists, tolerance_ns, &labels, &mut stats);
    unused_cameras(euroc_root.as_deref().unwrap_or(dir), cams, &mut stats)?;
    Ok((frames, stats))
}

/// Warns of the camera folders after the chain's `cams` cameras that hold images (a camchain of
/// cam0 alone beside a `cam1/` full of images): their images are not used, and the poses come
/// from fewer cameras than the folder offers.
fn unused_cameras(root: &Path, cams: usize, stats: &mut ScanStats) -> Result<()> {
    for c in cams.. {
        let folder = root.join(format!("cam{c}"));
        if !folder.is_dir() {
            break;
        }
        let mut ignored = 0;
        let n = match stats.layout {
            Layout::Euroc if folder.join("data.csv").is_file() => {
                read_euroc_csv(&folder.join("data.csv"), &folder.join("data"), &mut ignored)?.len()
            }
            Layout::Euroc => 0,
            _ => list_folder(&folder, &mut ignored)?.len(),
        };
        if n == 0 {
            continue;
        }
        let chain = match cams {
            1 => "the camera chain has cam0 alone".to_string(),
            n => format!("the camera chain has {n} cameras (cam0 to cam{})", n - 1),
        };
        stats.warnings.push(format!(
            "{}: {n} images not used: {chain}, so the poses come from {}; give a camchain with \
             cam{c} (dvlcal calibrate-cameras calibrates every camN folder) to use them",
            folder.display(),
            used_cameras_words(&(0..cams).collect::<Vec<_>>())
        ));
    }
    Ok(())
}

/// The cameras `used` in words: `cam0 alone`, `cam0 and cam1 (stereo)`, `cam0, cam1 and cam2`.
fn used_cameras_words(used: &[usize]) -> String {
    let names: Vec<String> = used.iter().map(|c| format!("cam{c}")).collect();
    match names.as_slice() {
        [] => "no camera".into(),
        [one] => format!("{one} alone"),
        [a, b] => format!("{a} and {b} (stereo)"),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// The image size of each of `cams` cameras, read from the header of its first image file that
/// opens; the error names the last file that did not.
pub fn image_sizes(frames: &[StereoFrame], cams: usize) -> Result<Vec<(u32, u32)>> {
    (0..cams)
        .map(|c| {
            let mut last_err = None;
            for p in frames
                .iter()
                .filter_map(|f| f.images.get(c).cloned().flatten())
                .filter_map(|r| r.path().map(Path::to_path_buf))
            {
                match image::image_dimensions(&p) {
                    Ok(d) => return Ok(d),
                    Err(e) => last_err = Some(format!("{}: {e}", p.display())),
                }
            }
            Err(Error::Input(format!(
                "cam{c}: no readable image{}",
                last_err.map_or(String::new(), |e| format!(" (last: {e})"))
            )))
        })
        .collect()
}

/// Frames from the time-sorted image lists of each camera (cam0 first, each list without
/// repeated stamps): every cam0 image is a frame; every other camera's image closest in time
/// within `tolerance_ns` joins it (each image at most once). A camera other than cam0 with no
/// images is left out with a warning (`missing[c]` says why); cam0 images without a partner
/// stay frames, other images without one are dropped; both are counted in `stats`.
pub fn pair_frames(
    lists: Vec<Vec<(i64, ImageRef)>>,
    tolerance_ns: i64,
    missing: &[String],
    stats: &mut ScanStats,
) -> Vec<StereoFrame> {
    let cams = lists.len();
    let used_cams: Vec<bool> = (0..cams).map(|c| c == 0 || !lists[c].is_empty()).collect();
    let used: Vec<usize> = (0..cams).filter(|&c| used_cams[c]).collect();
    for c in (1..cams).filter(|&c| !used_cams[c]) {
        let why = missing
            .get(c)
            .cloned()
            .unwrap_or_else(|| format!("cam{c}: no images"));
        stats.warnings.push(format!(
            "{why}; poses from {}, cam{c} of the camera chain not used",
            used_cameras_words(&used)
        ));
    }
    let Some(first) = lists.first() else {
        return Vec::new();
    };
    let mut frames: Vec<StereoFrame> = first
        .iter()
        .map(|(t, p)| {
            let mut images = vec![None; cams];
            images[0] = Some(p.clone());
            StereoFrame { t_ns: *t, images }
        })
        .collect();
    for c in (1..cams).filter(|&c| used_cams[c]) {
        let partner = pair(first, &lists[c], tolerance_ns);
        let mut taken = 0;
        for (f, m) in frames.iter_mut().zip(&partner) {
            if let Some(j) = m {
                f.images[c] = Some(lists[c][*j].1.clone());
                taken += 1;
            }
        }
        stats.unpaired_other += lists[c].len() - taken;
    }
    for f in &frames {
        let all = (0..cams).all(|c| !used_cams[c] || f.images[c].is_some());
        if all {
            stats.complete += 1;
        } else {
            stats.unpaired_cam0 += 1;
        }
    }
    if stats.unpaired_cam0 > 0 || stats.unpaired_other > 0 {
        let posed = if used.len() > 2 {
            "posed from the cameras that have an image"
        } else {
            "posed from cam0 alone"
        };
        stats.warnings.push(format!(
            "{} cam0 images without a partner within {} ms ({posed}), {} images of other cameras \
             without a cam0 partner (dropped)",
            stats.unpaired_cam0,
            tolerance_ns as f64 * 1e-6,
            stats.unpaired_other
        ));
    }
    frames
}

/// For each time of `a` (sorted), the index of its partner in `b` (sorted): pairs are formed
/// closest first, each element used at most once, within `tol`.
fn pair<T>(a: &[(i64, T)], b: &[(i64, T)], tol: i64) -> Vec<Option<usize>> {
    // Candidate pairs within tolerance, found with a sliding window, then taken in order of
    // increasing time difference (ties by position, so the result does not depend on anything else).
    let mut cand: Vec<(i64, usize, usize)> = Vec::new();
    let mut lo = 0;
    for (i, (ta, _)) in a.iter().enumerate() {
        while lo < b.len() && b[lo].0 < ta.saturating_sub(tol) {
            lo += 1;
        }
        let mut j = lo;
        while j < b.len() && b[j].0 <= ta.saturating_add(tol) {
            cand.push(((b[j].0 - ta).abs(), i, j));
            j += 1;
        }
    }
    cand.sort();
    let mut out = vec![None; a.len()];
    let mut used = vec![false; b.len()];
    for (_, i, j) in cand {
        if out[i].is_none() && !used[j] {
            out[i] = Some(j);
            used[j] = true;
        }
    }
    out
}

fn is_image(name: &str) -> bool {
    name.rsplit_once('.')
        .is_some_and(|(_, e)| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// A time stamp as a file name (or a EuRoC CSV line) writes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Stamp {
    /// Digits alone: the unit is decided per camera by [`to_nanos`].
    Integer(i64),
    /// `<seconds>.<fraction>`: nanoseconds, exactly.
    Seconds(i64),
}

/// The time stamp of a file name `<stamp>.<ext>`: integer digits, or decimal seconds.
fn stamp_of(name: &str) -> Option<Stamp> {
    let (stem, _) = name.rsplit_once('.')?;
    parse_stamp(stem)
}

fn parse_stamp(text: &str) -> Option<Stamp> {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    match text.split_once('.') {
        None if digits(text) => text.parse().ok().map(Stamp::Integer),
        Some((int, frac)) if digits(int) && digits(frac) && frac.len() <= 9 => {
            let sec: i64 = int.parse().ok()?;
            let nanos: i64 = format!("{frac:0<9}").parse().ok()?;
            sec.checked_mul(1_000_000_000)?
                .checked_add(nanos)
                .map(Stamp::Seconds)
        }
        _ => None,
    }
}

/// The units integer stamps may be in, with their size in nanoseconds.
const UNITS: [(&str, i64); 4] = [
    ("nanoseconds", 1),
    ("microseconds", 1_000),
    ("milliseconds", 1_000_000),
    ("seconds", 1_000_000_000),
];

/// Unix times from 2000 to 2100, in nanoseconds.
const UNIX_NS: std::ops::RangeInclusive<i128> = 946_684_800_000_000_000..=4_102_444_800_000_000_000;

/// Converts one camera's stamps to nanoseconds. Integer stamps are nanoseconds (Kalibr's and
/// EuRoC's convention) unless another unit is the one that makes them both Unix times (2000 to
/// 2100) and a camera's frame rate (0.05 Hz to 500 Hz): file names in milliseconds or
/// microseconds are then read as such, with a warning that says so. Stamps that fit no unit are
/// kept as nanoseconds with a warning. Stamps that overflow are counted in `ignored`.
fn to_nanos(
    list: Vec<(Stamp, PathBuf)>,
    label: &str,
    ignored: &mut usize,
    warnings: &mut Vec<String>,
) -> Vec<(i64, PathBuf)> {
    let mut ints: Vec<i64> = list
        .iter()
        .filter_map(|(s, _)| match s {
            Stamp::Integer(v) => Some(*v),
            Stamp::Seconds(_) => None,
        })
        .collect();
    ints.sort_unstable();
    ints.dedup();
    let mut factor = 1i64;
    if let Some(&median) = ints.get(ints.len() / 2) {
        let mut gaps: Vec<i64> = ints.windows(2).map(|w| w[1] - w[0]).collect();
        gaps.sort_unstable();
        let gap = gaps.get(gaps.len() / 2).copied();
        let unix = |f: i64| UNIX_NS.contains(&(median as i128 * f as i128));
        let rate_ok = |f: i64| {
            gap.is_none_or(|g| {
                let hz = 1e9 / (g as f64 * f as f64);
                (0.05..=500.0).contains(&hz)
            })
        };
        let chosen = UNITS
            .iter()
            .find(|(_, f)| unix(*f) && rate_ok(*f))
            .or_else(|| UNITS.iter().find(|(_, f)| rate_ok(*f)));
        match chosen {
            Some((name, f)) => {
                factor = *f;
                if *f != 1 {
                    let why = if unix(*f) {
                        "as nanoseconds they would not be Unix times, as"
                    } else {
                        "as nanoseconds the frame rate would not be a camera's, as"
                    };
                    warnings.push(format!(
                        "{label}: file names read as {name} ({why} {name} they are{})",
                        gap.map_or(String::new(), |g| format!(
                            " with {:.3} Hz frames",
                            1e9 / (g as f64 * *f as f64)
                        ))
                    ));
                }
            }
            None => warnings.push(format!(
                "{label}: time stamps read as nanoseconds, but their spacing ({} units) is no \
                 camera's frame rate in any unit: check the file names",
                gap.unwrap_or(0)
            )),
        }
    }
    list.into_iter()
        .filter_map(|(s, p)| {
            let ns = match s {
                Stamp::Integer(v) => v.checked_mul(factor),
                Stamp::Seconds(ns) => Some(ns),
            };
            if ns.is_none() {
                *ignored += 1;
            }
            ns.map(|t| (t, p))
        })
        .collect()
}

fn list_folder(folder: &Path, ignored: &mut usize) -> Result<Vec<(Stamp, PathBuf)>> {
    let rd = std::fs::read_dir(folder).map_err(|e| Error::io(folder, e))?;
    let mut out = Vec::new();
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(folder, e))?;
        let path = entry.path();
        if path.is_dir() {
            continue;
        }
        let name = entry.file_name().to_string_lossy().into_owned();
        match (is_image(&name), stamp_of(&name)) {
            (true, Some(t)) => out.push((t, path)),
            _ => *ignored += 1,
        }
    }
    Ok(out)
}

/// EuRoC's `data.csv`: `#timestamp [ns],filename` header, then `t_ns,name` lines.
fn read_euroc_csv(csv: &Path, data: &Path, ignored: &mut usize) -> Result<Vec<(Stamp, PathBuf)>> {
    let text = crate::files::read_text(csv)?;
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut f = line.split(',').map(str::trim);
        let (Some(t), Some(name)) = (f.next(), f.next()) else {
            *ignored += 1;
            continue;
        };
        match parse_stamp(t) {
            Some(t) if !name.is_empty() => out.push((t, data.join(name))),
            _ => *ignored += 1,
        }
    }
    Ok(out)
}

/// Seconds of a nanosecond stamp, exactly, as the crate's raw time.
pub fn raw_time(t_ns: i64) -> crate::time::RawTime {
    crate::time::RawTime::from_nanos(t_ns)
}
