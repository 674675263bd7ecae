//! A temporary folder for a test, removed when the test ends (pass or fail), and the built
//! program run with arguments.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The built `dvlcal` run with `args`, its output captured.
#[allow(dead_code)] // not every test binary that includes this module runs the program
pub fn dvlcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .expect("run dvlcal")
}

/// The built `dvlcal` run with `args`, asserted to succeed: its standard output.
#[allow(dead_code)]
pub fn dvlcal_ok(args: &[&str]) -> String {
    let out = dvlcal(args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "dvlcal {args:?}: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `dvlcal simulate --imu` of 60 s (seed 4) into `dir`: a recording with an IMU and its noise
/// file whose calibration the motion determines well.
#[allow(dead_code)]
pub fn simulate_imu_recording(dir: &Path) {
    dvlcal_ok(&[
        "simulate",
        "--imu",
        "--duration",
        "60",
        "--seed",
        "4",
        "--out",
        s(dir),
    ]);
}

/// A path as an argument (test paths are UTF-8).
#[allow(dead_code)]
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

pub struct TmpDir(pub PathBuf);

impl TmpDir {
    /// A fresh, empty folder named after the test's `tag` and the process.
    pub fn new(tag: &str) -> TmpDir {
        let d = std::env::temp_dir().join(format!("dvlcal-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("create a temporary folder");
        TmpDir(d)
    }

    /// `name` inside the folder.
    #[allow(dead_code)] // not every test binary that includes this module names files in it
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TmpDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A file of a sample and how to rewrite its text.
pub type Edit<'a> = (&'a str, &'a dyn Fn(&str) -> String);

/// A copy of the sample `src` (its parts symlinked, except those `edit` rewrites).
#[allow(dead_code)] // not every test binary that includes this module copies a sample
pub fn sample(tmp: &TmpDir, src: &str, name: &str, edit: &[Edit]) -> PathBuf {
    let d = tmp.path(name);
    std::fs::create_dir_all(&d).unwrap();
    for entry in std::fs::read_dir(src).unwrap() {
        let entry = entry.unwrap();
        let file = entry.file_name().to_string_lossy().into_owned();
        match edit.iter().find(|(f, _)| *f == file) {
            Some((_, change)) => {
                let text = std::fs::read_to_string(entry.path()).unwrap();
                std::fs::write(d.join(&file), change(&text)).unwrap();
            }
            None => std::os::unix::fs::symlink(entry.path(), d.join(&file)).unwrap(),
        }
    }
    d
}
