//! Finds the parts of a calibration dataset in one folder.
//!
//! A dataset folder holds the images (`cam0/`, `cam1/` in Kalibr's bag-creator layout, or
//! EuRoC's `mav0/camN/`), a Kalibr camchain YAML, a board (target) YAML and a DVL log in any
//! format the ingest reads. A bag (a ROS 1 `.bag`, a ROS 2 `.mcap` or `.db3`, or a ROS 2 bag
//! folder with `metadata.yaml`) may stand in for the images (or poses) and the DVL log: it
//! gives what the folder's own files do not. A bag may also be the dataset itself. The camchain may be missing: the pipeline then calibrates the
//! cameras from the same images first. Instead of images it may hold a TUM pose file. Only the folder's
//! own files are looked at, not its subfolders (a `truth/` folder beside the data is never
//! mistaken for data).
//!
//! Files are recognised by their content, not only their names: a YAML with a top-level `cam0`
//! entry with intrinsics is a camchain, one with `target_type` (Kalibr) or `tags` / `rows` (dvlcal) is a board,
//! one with `T_cam_dvl` (at the top, or in `cam0`: a result or a camchain-imucam dvlcal wrote) is
//! ignored; a file whose first lines look
//! like A50 output (or a ROS1 bag) is a DVL log; a text file whose lines hold eight numbers is a
//! TUM pose file (with the covariances of `POSES.frames.csv` beside it, when there is one). When
//! two files compete for one role the error names both.
//!
//! An IMU is optional: its stream is `imu0/data.csv` (EuRoC's `mav0/imu0/data.csv`), its noise
//! a YAML holding Kalibr's four noise keys (`imu.yaml`; at the top level or under `imu0`), or
//! else EuRoC's `imu0/sensor.yaml` beside the stream. A YAML with only some of the noise keys
//! is listed as ignored with the keys it lacks. An IMU stream or noise file named explicitly
//! wins: the folder's own is then listed as ignored, saying which is used instead. A folder
//! with an IMU stream needs no DVL log (a camera + IMU calibration); without either, the
//! missing DVL log is the error.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::bag::is_bag;
use crate::io::bag::roles::BagOptions;
use crate::io::dvl::detect::detect_format;
use crate::io::dvl::{DvlFormat, json, serial, text_lines};
use crate::io::frames_csv::frames_csv_path;
use crate::io::imu::noise::{noise_keys_in, without_opencv_directive};

/// What was found in (or given for) a dataset.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DatasetFiles {
    /// The dataset folder that was searched.
    pub root: PathBuf,
    /// The folder holding `cam0/` (or `mav0/`): the dataset folder itself.
    pub images: Option<PathBuf>,
    /// The Kalibr camchain YAML; `None` with images: the cameras are to be calibrated from the
    /// images themselves (see [`DatasetFiles::calibrates_cameras`]).
    pub camchain: Option<PathBuf>,
    /// The board (target) YAML.
    pub target: Option<PathBuf>,
    /// The DVL log.
    pub dvl: Option<PathBuf>,
    /// The TUM pose file, used instead of images.
    pub poses: Option<PathBuf>,
    /// The bag giving the camera data (images or poses), when neither image folders nor a
    /// pose file do. (A bag giving only the DVL data is in `dvl`.)
    pub bag: Option<PathBuf>,
    /// The IMU stream (EuRoC's IMU CSV, `imu0/data.csv` or `mav0/imu0/data.csv`).
    pub imu: Option<PathBuf>,
    /// The IMU's noise (Kalibr's `imu.yaml`, or EuRoC's `imu0/sensor.yaml`).
    pub imu_noise: Option<PathBuf>,
    /// Which topics of a bag play which part, and which time to use.
    pub bag_options: BagOptions,
    /// Files looked at and not used, with the reason (for the summary).
    pub ignored: Vec<(PathBuf, String)>,
}

impl DatasetFiles {
    /// The input files (camchain, target, DVL log, pose file and its covariance table, bag,
    /// IMU stream and noise): what no output may overwrite.
    pub fn inputs(&self) -> Vec<PathBuf> {
        [
            &self.camchain,
            &self.target,
            &self.dvl,
            &self.poses,
            &self.pose_covariances(),
            &self.bag,
            &self.imu,
            &self.imu_noise,
        ]
        .into_iter()
        .flatten()
        .cloned()
        .collect()
    }

    /// The table of the pose file's covariances (`POSES.frames.csv`, as `dvlcal detect` writes
    /// it beside the poses), when there is a pose file and the table sits beside it.
    pub fn pose_covariances(&self) -> Option<PathBuf> {
        self.poses
            .as_deref()
            .map(frames_csv_path)
            .filter(|f| f.is_file())
    }

    /// Whether the camera trajectory comes from images that have no camchain: the cameras must
    /// then be calibrated from those images (and the board) before the poses are solved.
    pub fn calibrates_cameras(&self) -> bool {
        self.poses.is_none() && self.images.is_some() && self.camchain.is_none()
    }

    /// A dataset that is one bag (`dvlcal calibrate run.mcap`): it gives the camera data and,
    /// unless `given` names a DVL log, the DVL data; camchain and target come from `given`.
    pub fn from_bag(bag: &Path, given: &DatasetOverrides) -> DatasetFiles {
        DatasetFiles {
            root: bag.to_path_buf(),
            images: given.images.clone(),
            camchain: given.camchain.clone(),
            target: given.target.clone(),
            dvl: Some(given.dvl.clone().unwrap_or_else(|| bag.to_path_buf())),
            poses: given.poses.clone(),
            bag: (given.images.is_none() && given.poses.is_none()).then(|| bag.to_path_buf()),
            imu: given.imu.clone(),
            imu_noise: given.imu_noise.clone(),
            bag_options: given.bag_options.clone(),
            ignored: Vec::new(),
        }
    }
}

/// Parts the user named explicitly; they win over what the folder holds, and a role given here
/// is not searched for.
#[derive(Clone, Debug, Default)]
pub struct DatasetOverrides {
    /// The images folder (holding `cam0/` or `mav0/`); wins over `poses`.
    pub images: Option<PathBuf>,
    /// The Kalibr camchain YAML.
    pub camchain: Option<PathBuf>,
    /// The board (target) YAML.
    pub target: Option<PathBuf>,
    /// The DVL log.
    pub dvl: Option<PathBuf>,
    /// The TUM pose file, used instead of images.
    pub poses: Option<PathBuf>,
    /// A bag for the camera data and, without a DVL log, the DVL data.
    pub bag: Option<PathBuf>,
    /// Which topics of a bag play which part, and which time to use.
    pub bag_options: BagOptions,
    /// The IMU stream (EuRoC's IMU CSV); wins over the folder's `imu0/data.csv` and a bag's
    /// IMU topic.
    pub imu: Option<PathBuf>,
    /// The IMU's noise (Kalibr's `imu.yaml`); wins over the folder's.
    pub imu_noise: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Camchain,
    Target,
    Dvl,
    Poses,
    Bag,
    ImuNoise,
}

impl Role {
    fn name(self) -> &'static str {
        match self {
            Role::Camchain => "camera chain (camchain YAML)",
            Role::Target => "board (target YAML)",
            Role::Dvl => "DVL log",
            Role::Poses => "pose file (TUM)",
            Role::Bag => "bag",
            Role::ImuNoise => "IMU noise (Kalibr imu.yaml)",
        }
    }
}

/// How many bytes of a file are read to recognise it.
const SNIFF_BYTES: usize = 64 * 1024;

fn sniff(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut buf = Vec::with_capacity(SNIFF_BYTES);
    f.by_ref()
        .take(SNIFF_BYTES as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    if buf.starts_with(crate::files::BOM) {
        buf.drain(..crate::files::BOM.len());
    }
    Ok(buf)
}

fn is_yaml(path: &Path) -> bool {
    matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("yaml" | "yml")
    )
}

/// The role of one YAML file from its top-level keys, or why it has none.
fn yaml_role(path: &Path) -> Result<std::result::Result<Role, String>> {
    let text = crate::files::read_text(path)?;
    let value: serde_yaml::Value = match serde_yaml::from_str(&text) {
        Ok(v) => v,
        Err(e) => return Ok(Err(format!("not readable as YAML ({e})"))),
    };
    let Some(map) = value.as_mapping() else {
        return Ok(Err("YAML but not a mapping".into()));
    };
    let has = |k: &str| map.contains_key(serde_yaml::Value::String(k.into()));
    let cam0 = map
        .get(serde_yaml::Value::String("cam0".into()))
        .and_then(|c| c.as_mapping());
    let cam0_has =
        |k: &str| cam0.is_some_and(|c| c.contains_key(serde_yaml::Value::String(k.into())));
    let (noise_found, noise_missing) = noise_keys_in(&value);
    Ok(if cam0_has("T_cam_dvl") {
        Err("a camchain-imucam with the DVL (dvlcal output)".into())
    } else if cam0_has("intrinsics") {
        Ok(Role::Camchain)
    } else if has("dvl0") {
        Err("a DVL extrinsics block (dvlcal output)".into())
    } else if has("target_type") || has("tags") || (has("rows") && has("cols")) {
        Ok(Role::Target)
    } else if has("T_cam_dvl") {
        Err("a calibration result".into())
    } else if noise_missing.is_empty() {
        Ok(Role::ImuNoise)
    } else if noise_found.len() >= 2 {
        Err(format!(
            "IMU noise keys ({}) without {}",
            noise_found.join(", "),
            noise_missing.join(", ")
        ))
    } else {
        Err("YAML of no known kind".into())
    })
}

/// Whether the text looks like a TUM pose file: its first data lines hold eight numbers.
fn looks_like_tum(bytes: &[u8]) -> bool {
    let text = String::from_utf8_lossy(bytes);
    let mut seen = 0;
    for line in text.lines().take(50) {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = t
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .collect();
        if fields.len() != 8 || fields.iter().any(|f| f.parse::<f64>().is_err()) {
            return false;
        }
        seen += 1;
        if seen >= 3 {
            break;
        }
    }
    seen > 0
}

/// The role of a non-YAML file from its first bytes.
fn data_role(path: &Path) -> Result<std::result::Result<Role, String>> {
    if is_bag(path) {
        return Ok(Ok(Role::Bag));
    }
    let bytes = sniff(path)?;
    match detect_format(&bytes) {
        Some(DvlFormat::RosBag) => return Ok(Ok(Role::Bag)),
        Some(f) => {
            // The format vote only looks at the shape of lines (a README mentioning `wrz` or
            // `{` would pass it); a DVL log must also hold at least one line that parses.
            let parse = |l: &[u8]| match f {
                DvlFormat::Serial => serial::parse_line(l).is_ok(),
                _ => json::parse_line(l).is_ok(),
            };
            if text_lines(&bytes).take(200).any(|(_, l)| parse(l)) {
                return Ok(Ok(Role::Dvl));
            }
        }
        None => {}
    }
    if looks_like_tum(&bytes) {
        return Ok(Ok(Role::Poses));
    }
    let first = String::from_utf8_lossy(&bytes[..bytes.len().min(512)]).into_owned();
    if first.trim_start().starts_with('#') && first.contains("w_RS_S_x") {
        return Ok(Err(
            "an IMU CSV (EuRoC's header): the IMU stream is read from imu0/data.csv".into(),
        ));
    }
    Ok(Err("not a known data file".into()))
}

/// The IMU stream of `dir`: `imu0/data.csv` or EuRoC's `mav0/imu0/data.csv` (both: an error
/// naming them).
fn find_imu(dir: &Path) -> Result<Option<PathBuf>> {
    let all: Vec<PathBuf> = [dir.join("imu0"), dir.join("mav0").join("imu0")]
        .into_iter()
        .map(|d| d.join("data.csv"))
        .filter(|p| p.is_file())
        .collect();
    match all.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(one.clone())),
        _ => Err(Error::Input(format!(
            "{}: several files could be the IMU stream: {}; keep one",
            dir.display(),
            all.iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// EuRoC's `sensor.yaml` beside the IMU stream, when it holds the noise keys.
fn sensor_yaml_noise(imu: &Path) -> Option<PathBuf> {
    let p = imu.parent()?.join("sensor.yaml");
    let text = crate::files::read_text(&p).ok()?;
    let value: serde_yaml::Value = serde_yaml::from_str(&without_opencv_directive(&text)).ok()?;
    noise_keys_in(&value).1.is_empty().then_some(p)
}

/// Whether `dir` holds images in a layout the image reader knows.
pub fn has_images(dir: &Path) -> bool {
    dir.join("cam0").is_dir() || dir.join("mav0").join("cam0").is_dir()
}

/// The files in `dir` (not in its subfolders) that [`discover`] would take for a DVL log, by
/// their content as it does (a bag is not counted: it may hold only images); files it cannot
/// read are left out, as it leaves them.
pub fn dvl_logs_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut logs: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && !is_yaml(p))
        .filter(|p| {
            !p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'))
        })
        .filter(|p| matches!(data_role(p), Ok(Ok(Role::Dvl))))
        .collect();
    logs.sort();
    Ok(logs)
}

/// Finds the dataset's parts in `dir`; `given` parts are taken as they are.
///
/// Errors: `dir` is not a folder; two files compete for one role (both named); images and a
/// pose file are both present and neither was chosen; no camera data or no DVL log is found;
/// images without a board. Images without a camchain are accepted (`camchain` is `None`): the
/// cameras are then calibrated from the same images.
pub fn discover(dir: &Path, given: &DatasetOverrides) -> Result<DatasetFiles> {
    if !dir.is_dir() {
        return Err(Error::Input(format!(
            "{}: not a folder (give the dataset folder, or --poses/--images and --dvl)",
            dir.display()
        )));
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        // Files, and ROS 2 bag folders (a folder with metadata.yaml).
        .filter(|p| p.is_file() || (p.is_dir() && is_bag(p)))
        .collect();
    entries.sort();

    let mut found = DatasetFiles {
        root: dir.to_path_buf(),
        ..Default::default()
    };
    let mut candidates: Vec<(Role, PathBuf)> = Vec::new();
    for p in entries {
        let hidden = p
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with('.'));
        if hidden {
            continue;
        }
        let role = if p.is_dir() {
            Ok(Ok(Role::Bag))
        } else if is_yaml(&p) {
            yaml_role(&p)
        } else {
            data_role(&p)
        };
        // A file that cannot be read cannot be a part either: it is listed with the reason
        // rather than stopping the search (a part named explicitly is still read, and fails,
        // later).
        match role {
            Ok(Ok(r)) => candidates.push((r, p)),
            Ok(Err(why)) => found.ignored.push((p, why)),
            Err(e) => found.ignored.push((p, format!("unreadable ({e})"))),
        }
    }
    let pick = |role: Role, given: &Option<PathBuf>| -> Result<Option<PathBuf>> {
        if let Some(g) = given {
            return Ok(Some(g.clone()));
        }
        let all: Vec<&PathBuf> = candidates
            .iter()
            .filter(|(r, _)| *r == role)
            .map(|(_, p)| p)
            .collect();
        match all.as_slice() {
            [] => Ok(None),
            [one] => Ok(Some((*one).clone())),
            many => Err(Error::Input(format!(
                "{}: several files could be the {}: {}; name one with its option",
                dir.display(),
                role.name(),
                many.iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))),
        }
    };
    found.camchain = pick(Role::Camchain, &given.camchain)?;
    found.target = pick(Role::Target, &given.target)?;
    found.dvl = pick(Role::Dvl, &given.dvl)?;
    found.imu = find_imu(dir)?;
    if let (Some(named), Some(here)) = (&given.imu, &found.imu) {
        found.ignored.push((
            here.clone(),
            format!("the IMU stream named instead ({}) is used", named.display()),
        ));
    }
    if given.imu.is_some() {
        found.imu = given.imu.clone();
    }
    let noise: Vec<&PathBuf> = candidates
        .iter()
        .filter(|(r, _)| *r == Role::ImuNoise)
        .map(|(_, p)| p)
        .collect();
    found.imu_noise = match noise.as_slice() {
        _ if given.imu_noise.is_some() => {
            for p in noise
                .iter()
                .filter(|p| given.imu_noise.as_ref() != Some(**p))
            {
                found.ignored.push((
                    (*p).clone(),
                    "the IMU noise file named instead is used".into(),
                ));
            }
            given.imu_noise.clone()
        }
        [] => found.imu.as_deref().and_then(sensor_yaml_noise),
        [one] => Some((*one).clone()),
        many => {
            return Err(Error::Input(format!(
                "{}: several files could be the {}: {}; keep one",
                dir.display(),
                Role::ImuNoise.name(),
                many.iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
    };
    found.bag_options = given.bag_options.clone();
    let bag = pick(Role::Bag, &given.bag)?;

    let images_here = has_images(dir).then(|| dir.to_path_buf());
    match (&given.images, &given.poses) {
        (Some(i), _) => found.images = Some(i.clone()),
        (None, Some(p)) => found.poses = Some(p.clone()),
        (None, None) => {
            let poses = pick(Role::Poses, &None)?;
            match (images_here, poses) {
                (Some(i), Some(p)) => {
                    return Err(Error::Input(format!(
                        "{}: both images ({}) and a pose file ({}) could give the camera \
                         trajectory; choose with --images or --poses",
                        dir.display(),
                        i.display(),
                        p.display()
                    )));
                }
                (i, p) => {
                    found.images = i;
                    found.poses = p;
                }
            }
        }
    }
    // The pose file's covariance table is part of the poses, not a file left unused.
    if let Some(table) = found.pose_covariances() {
        found.ignored.retain(|(p, _)| *p != table);
    }
    if found.images.is_none() && found.poses.is_none() {
        found.bag = bag.clone();
    }
    if found.dvl.is_none() {
        found.dvl = bag;
    }
    // No camera at all: only a DVL log with an IMU (the DVL + IMU mode) makes a dataset.
    let imu_beside_dvl = found.imu.is_some() && found.dvl.is_some();
    if found.images.is_none() && found.poses.is_none() && found.bag.is_none() && !imu_beside_dvl {
        return Err(Error::Input(format!(
            "{}: no camera data: neither cam0/ (or mav0/cam0/) images, a TUM pose file nor a bag",
            dir.display()
        )));
    }
    if found.images.is_some() && found.target.is_none() {
        return Err(Error::Input(format!(
            "{}: images but no board (target YAML)",
            dir.display()
        )));
    }
    if found.dvl.is_none() && found.imu.is_none() {
        return Err(Error::Input(format!(
            "{}: no DVL log (A50 JSON lines, serial capture or a ROS bag) found",
            dir.display()
        )));
    }
    Ok(found)
}
