//! One dataset (camera trajectory and DVL log) read into memory: from a dataset folder, from
//! files named one by one, or both (named files win).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::dataset::{DatasetFiles, DatasetOverrides, discover};
use crate::io::dvl::{DvlLog, DvlReadOptions, read_dvl_log};
use crate::io::tum::read_tum;
use crate::types::PoseMeasurement;

use super::vision::{VisionOptions, VisionRun, poses_from_images};

/// The files of a dataset: found in `dir` with `given` taking precedence, or, without a folder,
/// exactly the files `given` names (a DVL log, and poses or images with a camchain and a target).
pub fn dataset_files(dir: Option<&Path>, given: &DatasetOverrides) -> Result<DatasetFiles> {
    if let Some(d) = dir {
        return discover(d, given);
    }
    let Some(dvl) = &given.dvl else {
        return Err(Error::Input(
            "give a dataset folder, or --dvl LOG with --poses FILE or --images DIR".into(),
        ));
    };
    match (&given.poses, &given.images) {
        (Some(_), _) => {}
        (None, Some(_)) => {
            if given.camchain.is_none() || given.target.is_none() {
                return Err(Error::Input(
                    "--images needs --camchain FILE and --target FILE".into(),
                ));
            }
        }
        (None, None) => {
            return Err(Error::Input(
                "give --poses FILE, or --images DIR --camchain FILE --target FILE".into(),
            ));
        }
    }
    Ok(DatasetFiles {
        root: PathBuf::from("."),
        images: given.images.clone(),
        camchain: given.camchain.clone(),
        target: given.target.clone(),
        dvl: Some(dvl.clone()),
        poses: given.poses.clone(),
        ignored: Vec::new(),
    })
}

/// One line on what a dataset folder holds, then one per ignored file with the reason.
pub fn describe_files(f: &DatasetFiles) -> String {
    let show = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or("-".to_string(), |p| p.display().to_string())
    };
    let mut s = format!(
        "dataset {}: images {}, poses {}, camchain {}, target {}, DVL log {}\n",
        f.root.display(),
        show(&f.images),
        show(&f.poses),
        show(&f.camchain),
        show(&f.target),
        show(&f.dvl)
    );
    for (p, why) in &f.ignored {
        s.push_str(&format!("  ignored {}: {why}\n", p.display()));
    }
    s
}

/// A dataset read into memory: the camera poses and the DVL log on one epoch.
#[derive(Debug)]
pub struct Dataset {
    /// Where each part came from.
    pub files: DatasetFiles,
    /// The camera poses `T_world_cam` on the camera clock.
    pub poses: Vec<PoseMeasurement>,
    /// The image pipeline's run, when the poses come from images.
    pub vision: Option<VisionRun>,
    /// The DVL log, read on the poses' epoch.
    pub log: DvlLog,
    /// The DVL log's file.
    pub dvl_path: PathBuf,
    /// What the camera trajectory came from: the pose file or the image folder.
    pub camera_source: PathBuf,
}

impl Dataset {
    /// Reads the camera trajectory (running the image pipeline on images) and the DVL log on
    /// its epoch. `on_vision` sees the image run as soon as detection ends, also when no frame
    /// got a pose (the error follows).
    pub fn load(
        files: DatasetFiles,
        vision: &VisionOptions,
        read: &DvlReadOptions,
        on_vision: &mut dyn FnMut(&VisionRun),
    ) -> Result<Dataset> {
        let (epoch, poses, run, camera_source) = match (&files.poses, &files.images) {
            (Some(p), _) => {
                let tum = read_tum(p, None)?;
                (tum.epoch, tum.poses, None, p.clone())
            }
            (None, Some(dir)) => {
                let (Some(chain), Some(target)) = (&files.camchain, &files.target) else {
                    return Err(Error::dataset(dir, "images need a camchain and a target"));
                };
                let run = poses_from_images(dir, chain, target, vision)?;
                on_vision(&run);
                run.require_poses()?;
                (run.epoch, run.poses.clone(), Some(run), dir.clone())
            }
            (None, None) => return Err(Error::dataset(&files.root, "no camera data")),
        };
        let Some(dvl_path) = files.dvl.clone() else {
            return Err(Error::dataset(&files.root, "no DVL log"));
        };
        let read = DvlReadOptions {
            epoch: Some(epoch),
            ..read.clone()
        };
        let log = read_dvl_log(&dvl_path, &read)?;
        Ok(Dataset {
            files,
            poses,
            vision: run,
            log,
            dvl_path,
            camera_source,
        })
    }

    /// The dataset's name in tables: its folder's last component.
    pub fn short_name(&self) -> String {
        self.files
            .root
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.files.root.display().to_string())
    }
}
