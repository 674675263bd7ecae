//! Loading one dataset (camera trajectory + DVL log) for `calibrate` and `evaluate`: from a
//! dataset folder, from explicit files, or both (explicit files win).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use clap::Args;

use dvlcal::io::dataset::{DatasetFiles, DatasetOverrides, discover};
use dvlcal::io::dvl::{DvlLog, DvlReadOptions, read_dvl_log};
use dvlcal::io::tum::read_tum;
use dvlcal::types::PoseMeasurement;

use crate::detect::{VisionRun, VisionTuning, run_pipeline};

/// The parts of a dataset that can be named on the command line.
#[derive(Args, Debug, Clone, Default)]
pub struct DatasetArgs {
    /// TUM file of T_world_cam (camera clock), instead of images.
    #[arg(long, conflicts_with = "images")]
    pub poses: Option<PathBuf>,
    /// Image folder (DIR/cam0, DIR/cam1 or EuRoC's DIR/mav0/camN): poses and their covariances
    /// come from `dvlcal detect`'s pipeline (needs a camchain and a target).
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// Kalibr camchain YAML, with images.
    #[arg(long, value_name = "FILE")]
    pub camchain: Option<PathBuf>,
    /// Board YAML (dvlcal grid or list, or a Kalibr aprilgrid), with images.
    #[arg(long, value_name = "FILE")]
    pub target: Option<PathBuf>,
    /// Water Linked A50 log: JSON lines (any json_v1..v3 version), serial capture or ROS1 bag.
    #[arg(long)]
    pub dvl: Option<PathBuf>,
}

impl DatasetArgs {
    fn overrides(&self) -> DatasetOverrides {
        DatasetOverrides {
            images: self.images.clone(),
            camchain: self.camchain.clone(),
            target: self.target.clone(),
            dvl: self.dvl.clone(),
            poses: self.poses.clone(),
        }
    }
}

/// The files of a dataset: found in `dir` (explicit ones win), or all explicit.
pub fn resolve(dir: Option<&Path>, a: &DatasetArgs) -> Result<DatasetFiles> {
    if let Some(d) = dir {
        let files = discover(d, &a.overrides())?;
        return Ok(files);
    }
    let Some(dvl) = &a.dvl else {
        bail!("give a dataset folder, or --dvl LOG with --poses FILE or --images DIR");
    };
    match (&a.poses, &a.images) {
        (Some(_), _) => {}
        (None, Some(_)) => {
            if a.camchain.is_none() || a.target.is_none() {
                bail!("--images needs --camchain FILE and --target FILE");
            }
        }
        (None, None) => bail!("give --poses FILE, or --images DIR --camchain FILE --target FILE"),
    }
    Ok(DatasetFiles {
        root: PathBuf::from("."),
        images: a.images.clone(),
        camchain: a.camchain.clone(),
        target: a.target.clone(),
        dvl: Some(dvl.clone()),
        poses: a.poses.clone(),
        ignored: Vec::new(),
    })
}

/// A dataset read into memory.
pub struct Loaded {
    pub files: DatasetFiles,
    pub poses: Vec<PoseMeasurement>,
    /// The vision run when the poses come from images.
    pub vision: Option<VisionRun>,
    pub log: DvlLog,
    pub dvl_path: PathBuf,
    /// What the camera trajectory came from (for messages).
    pub camera_source: PathBuf,
}

/// Prints what was found in a dataset folder.
pub fn print_found(f: &DatasetFiles) {
    let show = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or("-".to_string(), |p| p.display().to_string())
    };
    println!(
        "dataset {}: images {}, poses {}, camchain {}, target {}, DVL log {}",
        f.root.display(),
        show(&f.images),
        show(&f.poses),
        show(&f.camchain),
        show(&f.target),
        show(&f.dvl)
    );
    for (p, why) in &f.ignored {
        println!("  ignored {}: {why}", p.display());
    }
}

/// Reads the camera trajectory (running detection on images) and the DVL log on its epoch.
pub fn load(files: DatasetFiles, tuning: &VisionTuning, read: &DvlReadOptions) -> Result<Loaded> {
    let (epoch, poses, vision, camera_source) = match (&files.poses, &files.images) {
        (Some(p), _) => {
            let tum = read_tum(p, None)?;
            (tum.epoch, tum.poses, None, p.clone())
        }
        (None, Some(dir)) => {
            let (Some(chain), Some(target)) = (&files.camchain, &files.target) else {
                bail!("{}: images need a camchain and a target", dir.display());
            };
            let run = run_pipeline(dir, chain, target, tuning)?;
            (run.epoch, run.poses.clone(), Some(run), dir.clone())
        }
        (None, None) => bail!("{}: no camera data", files.root.display()),
    };
    let Some(dvl_path) = files.dvl.clone() else {
        bail!("{}: no DVL log", files.root.display());
    };
    let mut read = read.clone();
    read.epoch = Some(epoch);
    let log = read_dvl_log(&dvl_path, &read)?;
    if log.stats.rejected_lines > 0 {
        eprintln!(
            "{}: {} malformed lines skipped (dvlcal dvl-info lists them)",
            dvl_path.display(),
            log.stats.rejected_lines
        );
    }
    Ok(Loaded {
        files,

        poses,
        vision,
        log,
        dvl_path,
        camera_source,
    })
}
