//! Which topic of a bag plays which part in a calibration, from the message types (and, where
//! types leave a choice, the names): the images (one camera or a stereo pair), their
//! `CameraInfo`, the DVL, and, for recordings without images, the camera's poses.
//!
//! The rules, in order:
//! - images: `sensor_msgs/Image` and `sensor_msgs/CompressedImage`; a compressed topic whose
//!   raw topic is also there (`X/compressed` beside `X`) is left for the raw one. One topic is a
//!   single camera; two are a stereo pair ordered by name (`left` before `right`, `cam0` before
//!   `cam1`, ...), and two that their names do not order, or more than two, are an error asking
//!   for `--image-topics L,R`.
//! - DVL: by kind, best first: `marine_acoustic_msgs/Dvl` (Water Linked's ROS 2 driver), the
//!   A50's JSON in `std_msgs/String` on a topic whose name says `dvl` (Water Linked's ROS 1
//!   driver), `waterlinked_a50_ros_driver/DVL`, `geometry_msgs/TwistWithCovarianceStamped`, and
//!   `nav_msgs/Odometry` on a topic whose name says `dvl` (the ROS 2 driver's `~/odom`). Two
//!   topics of the best kind present are an error naming both.
//! - IMU: `sensor_msgs/Imu`, when the bag holds exactly one such topic; two or more are an error
//!   naming them all (raised when the IMU is read; a listing notes it).
//! - poses: `geometry_msgs/PoseStamped`, `PoseWithCovarianceStamped`, `TransformStamped`,
//!   `nav_msgs/Odometry` and `tf2_msgs/TFMessage` (the latter with a child frame named), but not
//!   the topics in the DVL's own namespace (the driver's dead reckoning and odometry). Two
//!   candidates are an error naming both.
//!
//! Whatever the user names (`--image-topics`, `--dvl-topic`, `--pose-topic`, `--imu-topic`)
//! wins, and must exist with a type that can play the part.

use std::fmt;
use std::str::FromStr;

use super::Topic;
use crate::error::{Error, Result};

/// Which time a message is placed at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BagTime {
    /// `header.stamp` (the time of the data, as Kalibr uses); a zero stamp falls back to the
    /// record time, counted and warned about.
    #[default]
    Header,
    /// The record time: when the recorder received the message (tens of ms late).
    Record,
}

impl BagOptions {
    /// The options of a command that reads a bag's images only: the image topics (cam0 first)
    /// and their time, no other topic named.
    pub fn images_only(image_topics: Option<Vec<String>>, time: BagTime) -> BagOptions {
        BagOptions {
            image_topics,
            time,
            ..BagOptions::default()
        }
    }
}

impl FromStr for BagTime {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "header" | "stamp" => Ok(BagTime::Header),
            "record" | "log" | "receive" => Ok(BagTime::Record),
            _ => Err(format!(
                "unknown bag time '{s}' (expected header or record)"
            )),
        }
    }
}

impl fmt::Display for BagTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BagTime::Header => "header",
            BagTime::Record => "record",
        })
    }
}

/// The topics the user named, and which time to use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BagOptions {
    /// The image topics, cam0 first (`--image-topics L[,R]`).
    pub image_topics: Option<Vec<String>>,
    /// The DVL topic (`--dvl-topic`).
    pub dvl_topic: Option<String>,
    /// The pose topic, for a bag without images (`--pose-topic`).
    pub pose_topic: Option<String>,
    /// The child frame whose transforms are the poses, for `tf2_msgs/TFMessage` topics
    /// (`--pose-frame`).
    pub pose_frame: Option<String>,
    /// The IMU topic (`--imu-topic`), when the bag holds more than one `sensor_msgs/Imu`.
    pub imu_topic: Option<String>,
    /// Header stamps or record times (`--bag-time`).
    pub time: BagTime,
}

/// What a topic's type can be to dvlcal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `sensor_msgs/Image`.
    Image,
    /// `sensor_msgs/CompressedImage`.
    CompressedImage,
    /// `sensor_msgs/CameraInfo`.
    CameraInfo,
    /// `marine_acoustic_msgs/Dvl`.
    MarineDvl,
    /// `std_msgs/String` (A50 JSON when on a DVL topic).
    String,
    /// `waterlinked_a50_ros_driver/DVL`.
    A50Dvl,
    /// `geometry_msgs/TwistWithCovarianceStamped`.
    TwistCov,
    /// `nav_msgs/Odometry`.
    Odometry,
    /// `geometry_msgs/PoseStamped`.
    PoseStamped,
    /// `geometry_msgs/PoseWithCovarianceStamped`.
    PoseCov,
    /// `geometry_msgs/TransformStamped`.
    Transform,
    /// `tf2_msgs/TFMessage`.
    Tf,
    /// `sensor_msgs/Imu`.
    Imu,
}

impl Kind {
    /// The kind of a normalised type name (`pkg/Type`), if dvlcal reads it.
    pub fn of(type_name: &str) -> Option<Kind> {
        Some(match type_name {
            "sensor_msgs/Image" => Kind::Image,
            "sensor_msgs/CompressedImage" => Kind::CompressedImage,
            "sensor_msgs/CameraInfo" => Kind::CameraInfo,
            "marine_acoustic_msgs/Dvl" => Kind::MarineDvl,
            "std_msgs/String" => Kind::String,
            "geometry_msgs/TwistWithCovarianceStamped" => Kind::TwistCov,
            "nav_msgs/Odometry" => Kind::Odometry,
            "geometry_msgs/PoseStamped" => Kind::PoseStamped,
            "geometry_msgs/PoseWithCovarianceStamped" => Kind::PoseCov,
            "geometry_msgs/TransformStamped" => Kind::Transform,
            "tf2_msgs/TFMessage" => Kind::Tf,
            "sensor_msgs/Imu" => Kind::Imu,
            t if t == "waterlinked_a50_ros_driver/DVL" || t.ends_with("/DVL") => Kind::A50Dvl,
            _ => return None,
        })
    }

    /// Whether messages of this kind are images.
    pub fn is_image(self) -> bool {
        matches!(self, Kind::Image | Kind::CompressedImage)
    }

    /// Whether messages of this kind can be the camera's poses.
    pub fn is_pose(self) -> bool {
        matches!(
            self,
            Kind::PoseStamped | Kind::PoseCov | Kind::Transform | Kind::Odometry | Kind::Tf
        )
    }

    /// Whether messages of this kind can be DVL velocities.
    pub fn is_dvl(self) -> bool {
        matches!(
            self,
            Kind::MarineDvl | Kind::String | Kind::A50Dvl | Kind::TwistCov | Kind::Odometry
        )
    }
}

/// The kind of a topic.
pub fn kind(t: &Topic) -> Option<Kind> {
    Kind::of(&t.type_name())
}

/// The parts the topics of a bag play (indices into the bag's topics).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Roles {
    /// The image topics, cam0 first (empty: no images).
    pub images: Vec<usize>,
    /// The `CameraInfo` topic of each image topic, when there is one.
    pub camera_info: Vec<Option<usize>>,
    /// The DVL topic.
    pub dvl: Option<usize>,
    /// The pose topic, looked for only when there are no images.
    pub pose: Option<usize>,
    /// The IMU topic (`sensor_msgs/Imu`): the named one, or the only one.
    pub imu: Option<usize>,
    /// How each choice was made, for the summary.
    pub notes: Vec<String>,
}

fn lower(s: &str) -> String {
    s.to_ascii_lowercase()
}

fn says_dvl(name: &str) -> bool {
    lower(name).contains("dvl")
}

/// The namespace of a topic: everything before its last `/`.
fn namespace(name: &str) -> &str {
    name.rsplit_once('/').map_or("", |(ns, _)| ns)
}

fn find(topics: &[Topic], name: &str) -> Option<usize> {
    topics.iter().position(|t| t.name == name)
}

/// Every topic with its type (`/cam0/image_raw [sensor_msgs/Image], ...`; `none` for none),
/// for error messages.
pub fn topic_list(topics: &[Topic]) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    listing(topics, &(0..topics.len()).collect::<Vec<_>>())
}

fn listing(topics: &[Topic], idx: &[usize]) -> String {
    idx.iter()
        .filter_map(|&i| topics.get(i))
        .map(|t| format!("{} [{}]", t.name, t.type_name()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The DVL rank of a topic (lower is better), if it can be the DVL without being named.
fn dvl_rank(t: &Topic) -> Option<u8> {
    match kind(t)? {
        Kind::MarineDvl => Some(0),
        Kind::String if says_dvl(&t.name) => Some(1),
        Kind::A50Dvl => Some(2),
        Kind::TwistCov => Some(3),
        Kind::Odometry if says_dvl(&t.name) => Some(4),
        _ => None,
    }
}

/// The DVL topic: the named one, or the best by kind; `None` when the bag has none.
pub fn choose_dvl(topics: &[Topic], named: Option<&str>) -> Result<Option<usize>> {
    if let Some(n) = named {
        let Some(i) = find(topics, n) else {
            return Err(Error::Input(format!(
                "--dvl-topic {n}: no such topic (topics: {})",
                topic_list(topics)
            )));
        };
        if !kind(&topics[i]).is_some_and(Kind::is_dvl) {
            return Err(Error::Input(format!(
                "--dvl-topic {n} has type {}; a DVL topic is marine_acoustic_msgs/Dvl, \
                 std_msgs/String (A50 JSON), waterlinked_a50_ros_driver/DVL, \
                 geometry_msgs/TwistWithCovarianceStamped or nav_msgs/Odometry",
                topics[i].type_name()
            )));
        }
        return Ok(Some(i));
    }
    let ranked: Vec<(u8, usize)> = topics
        .iter()
        .enumerate()
        .filter_map(|(i, t)| dvl_rank(t).map(|r| (r, i)))
        .collect();
    let Some(best) = ranked.iter().map(|(r, _)| *r).min() else {
        return Ok(None);
    };
    let top: Vec<usize> = ranked
        .iter()
        .filter(|(r, _)| *r == best)
        .map(|(_, i)| *i)
        .collect();
    if top.len() > 1 {
        return Err(Error::Input(format!(
            "two DVL topics of one kind: {}; choose one with --dvl-topic",
            listing(topics, &top)
        )));
    }
    Ok(top.first().copied())
}

/// The order a name gives a camera in a stereo pair (0 left, 1 right), if it gives one.
fn side(name: &str) -> Option<u8> {
    let n = lower(name);
    let has = |w: &str| n.contains(w);
    let left = has("left") || has("cam0") || has("camera0") || has("camera_0") || has("cam_0");
    let right = has("right") || has("cam1") || has("camera1") || has("camera_1") || has("cam_1");
    match (left, right) {
        (true, false) => Some(0),
        (false, true) => Some(1),
        _ => None,
    }
}

/// The image topics, cam0 first: the named ones, or those the types and names give.
pub fn choose_images(topics: &[Topic], named: Option<&[String]>) -> Result<Vec<usize>> {
    if let Some(names) = named {
        let mut out = Vec::new();
        for n in names {
            let Some(i) = find(topics, n) else {
                return Err(Error::Input(format!(
                    "--image-topics: no topic {n} (image topics: {})",
                    listing(topics, &image_candidates(topics))
                )));
            };
            if !kind(&topics[i]).is_some_and(Kind::is_image) {
                return Err(Error::Input(format!(
                    "--image-topics: {n} has type {}, not sensor_msgs/Image or CompressedImage",
                    topics[i].type_name()
                )));
            }
            out.push(i);
        }
        return Ok(out);
    }
    let cands = image_candidates(topics);
    match cands.len() {
        0 | 1 => Ok(cands),
        2 => {
            let (a, b) = (cands[0], cands[1]);
            match (side(&topics[a].name), side(&topics[b].name)) {
                (Some(0), Some(1)) => Ok(vec![a, b]),
                (Some(1), Some(0)) => Ok(vec![b, a]),
                _ => Err(Error::Input(format!(
                    "two image topics whose names do not say which is left: {}; give \
                     --image-topics LEFT,RIGHT",
                    listing(topics, &cands)
                ))),
            }
        }
        _ => Err(Error::Input(format!(
            "{} image topics: {}; give --image-topics L[,R]",
            cands.len(),
            listing(topics, &cands)
        ))),
    }
}

/// Image topics, without a compressed topic whose raw topic is also there.
fn image_candidates(topics: &[Topic]) -> Vec<usize> {
    let images: Vec<usize> = (0..topics.len())
        .filter(|&i| kind(&topics[i]).is_some_and(Kind::is_image))
        .collect();
    images
        .iter()
        .copied()
        .filter(|&i| {
            let t = &topics[i];
            let raw_beside = kind(t) == Some(Kind::CompressedImage)
                && t.name.strip_suffix("/compressed").is_some_and(|raw| {
                    images
                        .iter()
                        .any(|&j| topics[j].name == raw && kind(&topics[j]) == Some(Kind::Image))
                });
            !raw_beside
        })
        .collect()
}

/// The `CameraInfo` topic of an image topic: in the same namespace, or the only one.
pub fn camera_info_for(topics: &[Topic], image: usize) -> Option<usize> {
    let infos: Vec<usize> = (0..topics.len())
        .filter(|&i| kind(&topics[i]) == Some(Kind::CameraInfo))
        .collect();
    let name = &topics.get(image)?.name;
    // `/cam0/image_raw/compressed` and `/cam0/image_raw` both belong with `/cam0/camera_info`.
    let base = name.strip_suffix("/compressed").unwrap_or(name);
    let ns = namespace(base);
    let same: Vec<usize> = infos
        .iter()
        .copied()
        .filter(|&i| namespace(&topics[i].name) == ns)
        .collect();
    match same.as_slice() {
        [one] => Some(*one),
        _ => None,
    }
}

/// The pose topic: the named one, or the only candidate outside the DVL's namespace; `None`
/// when there is none.
pub fn choose_pose(
    topics: &[Topic],
    named: Option<&str>,
    dvl: Option<usize>,
) -> Result<Option<usize>> {
    if let Some(n) = named {
        let Some(i) = find(topics, n) else {
            return Err(Error::Input(format!(
                "--pose-topic {n}: no such topic (topics: {})",
                topic_list(topics)
            )));
        };
        if !kind(&topics[i]).is_some_and(Kind::is_pose) {
            return Err(Error::Input(format!(
                "--pose-topic {n} has type {}; a pose topic is geometry_msgs/PoseStamped, \
                 PoseWithCovarianceStamped, TransformStamped, nav_msgs/Odometry or \
                 tf2_msgs/TFMessage",
                topics[i].type_name()
            )));
        }
        return Ok(Some(i));
    }
    let dvl_ns = dvl.and_then(|d| topics.get(d)).map(|t| namespace(&t.name));
    let cands: Vec<usize> = (0..topics.len())
        .filter(|&i| {
            let t = &topics[i];
            kind(t).is_some_and(Kind::is_pose)
                && Some(i) != dvl
                && !(dvl_ns.is_some_and(|ns| !ns.is_empty() && namespace(&t.name) == ns))
                && !(kind(t) == Some(Kind::Odometry) && says_dvl(&t.name))
                // `/tf_static` holds fixed frames, not a trajectory.
                && t.name != "/tf_static"
        })
        .collect();
    match cands.len() {
        0 => Ok(None),
        1 => Ok(Some(cands[0])),
        _ => Err(Error::Input(format!(
            "several pose topics: {}; choose one with --pose-topic",
            listing(topics, &cands)
        ))),
    }
}

/// The IMU topic: the named one (which must be a `sensor_msgs/Imu`), or the only
/// `sensor_msgs/Imu` topic; `None` when the bag has none. Two or more, none named, are an error
/// listing them and asking for `--imu-topic`.
pub fn choose_imu(topics: &[Topic], named: Option<&str>) -> Result<Option<usize>> {
    if let Some(n) = named {
        let Some(i) = find(topics, n) else {
            return Err(Error::Input(format!(
                "--imu-topic {n}: no such topic (topics: {})",
                topic_list(topics)
            )));
        };
        if kind(&topics[i]) != Some(Kind::Imu) {
            return Err(Error::Input(format!(
                "--imu-topic {n} has type {}; an IMU topic is sensor_msgs/Imu",
                topics[i].type_name()
            )));
        }
        return Ok(Some(i));
    }
    let cands: Vec<usize> = (0..topics.len())
        .filter(|&i| kind(&topics[i]) == Some(Kind::Imu))
        .collect();
    match cands.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(*one)),
        _ => Err(Error::Input(format!(
            "{} sensor_msgs/Imu topics: {}; choose one with --imu-topic",
            cands.len(),
            listing(topics, &cands)
        ))),
    }
}

/// Assigns the roles: images (with their `CameraInfo`), DVL, and poses when there are no
/// images. Nothing found for a role is not an error here (the caller knows what it needs).
pub fn assign(topics: &[Topic], opts: &BagOptions) -> Result<Roles> {
    let images = choose_images(topics, opts.image_topics.as_deref())?;
    let mut notes = Vec::new();
    // Two DVL topics are the DVL reader's error to raise (a command that reads only the images
    // does not need to choose); a topic named and missing is an error now.
    let dvl = match choose_dvl(topics, opts.dvl_topic.as_deref()) {
        Ok(d) => d,
        Err(e) if opts.dvl_topic.is_none() => {
            notes.push(e.to_string());
            None
        }
        Err(e) => return Err(e),
    };
    let pose = if images.is_empty() || opts.pose_topic.is_some() {
        choose_pose(topics, opts.pose_topic.as_deref(), dvl)?
    } else {
        None
    };
    // As for the DVL: two IMU topics are the IMU reader's error; a named one missing is one now.
    let imu = match choose_imu(topics, opts.imu_topic.as_deref()) {
        Ok(i) => i,
        Err(e) if opts.imu_topic.is_none() => {
            notes.push(e.to_string());
            None
        }
        Err(e) => return Err(e),
    };
    let camera_info = images.iter().map(|&i| camera_info_for(topics, i)).collect();
    if let Some(d) = dvl {
        let others: Vec<usize> = (0..topics.len())
            .filter(|&i| i != d && dvl_rank(&topics[i]).is_some())
            .collect();
        if !others.is_empty() && opts.dvl_topic.is_none() {
            notes.push(format!(
                "DVL from {} (also present: {})",
                topics[d].name,
                listing(topics, &others)
            ));
        }
    }
    Ok(Roles {
        images,
        camera_info,
        dvl,
        pose,
        imu,
        notes,
    })
}

/// The role of topic `i` under `roles`, for listings (`-` for none).
pub fn role_name(roles: &Roles, i: usize) -> String {
    if let Some(c) = roles.images.iter().position(|&t| t == i) {
        return format!("images cam{c}");
    }
    if let Some(c) = roles.camera_info.iter().position(|&t| t == Some(i)) {
        return format!("camera info cam{c}");
    }
    if roles.dvl == Some(i) {
        return "DVL".into();
    }
    if roles.pose == Some(i) {
        return "camera poses".into();
    }
    if roles.imu == Some(i) {
        return "IMU".into();
    }
    "-".into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::bag::Serialization;

    fn t(name: &str, ty: &str) -> Topic {
        Topic {
            name: name.into(),
            msg_type: ty.into(),
            serialization: Serialization::Cdr,
            declared_count: None,
        }
    }

    #[test]
    fn water_linked_ros2_driver_gives_the_dvl_message_not_odom_or_dead_reckoning() {
        let topics = vec![
            t("/dvl/odom", "nav_msgs/msg/Odometry"),
            t("/dvl/velocity_report", "marine_acoustic_msgs/msg/Dvl"),
            t(
                "/dvl/dead_reckoning_report",
                "geometry_msgs/msg/PoseWithCovarianceStamped",
            ),
            t("/mocap/rig/pose", "geometry_msgs/msg/PoseStamped"),
        ];
        let r = assign(&topics, &BagOptions::default()).unwrap();
        assert_eq!(r.dvl, Some(1));
        assert_eq!(r.pose, Some(3));
        assert!(r.images.is_empty());
        assert!(r.notes[0].contains("/dvl/odom"));
    }

    #[test]
    fn stereo_pairs_by_name_and_prefers_raw() {
        let topics = vec![
            t("/stereo/right/image_raw", "sensor_msgs/msg/Image"),
            t("/stereo/left/image_raw", "sensor_msgs/msg/Image"),
            t(
                "/stereo/left/image_raw/compressed",
                "sensor_msgs/msg/CompressedImage",
            ),
            t("/stereo/left/camera_info", "sensor_msgs/msg/CameraInfo"),
            t("/stereo/right/camera_info", "sensor_msgs/msg/CameraInfo"),
        ];
        let r = assign(&topics, &BagOptions::default()).unwrap();
        assert_eq!(r.images, vec![1, 0]);
        assert_eq!(r.camera_info, vec![Some(3), Some(4)]);
        let topics = vec![
            t("/a/image", "sensor_msgs/Image"),
            t("/b/image", "sensor_msgs/Image"),
        ];
        let e = assign(&topics, &BagOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/a/image") && e.contains("--image-topics"),
            "{e}"
        );
        let named = BagOptions {
            image_topics: Some(vec!["/b/image".into(), "/a/image".into()]),
            ..BagOptions::default()
        };
        assert_eq!(assign(&topics, &named).unwrap().images, vec![1, 0]);
    }

    #[test]
    fn two_candidates_are_an_error_naming_both() {
        let topics = vec![
            t("/dvl_a/velocity_report", "marine_acoustic_msgs/msg/Dvl"),
            t("/dvl_b/velocity_report", "marine_acoustic_msgs/msg/Dvl"),
        ];
        let e = choose_dvl(&topics, None).unwrap_err().to_string();
        assert!(e.contains("/dvl_a/") && e.contains("/dvl_b/") && e.contains("--dvl-topic"));
        assert_eq!(
            choose_dvl(&topics, Some("/dvl_b/velocity_report")).unwrap(),
            Some(1)
        );
        let topics = vec![
            t("/vio/pose", "geometry_msgs/msg/PoseWithCovarianceStamped"),
            t("/vio/odom", "nav_msgs/msg/Odometry"),
        ];
        let e = choose_pose(&topics, None, None).unwrap_err().to_string();
        assert!(e.contains("/vio/pose") && e.contains("/vio/odom"), "{e}");
        assert!(choose_pose(&topics, Some("/nope"), None).is_err());
        assert!(choose_dvl(&topics, Some("/vio/pose")).is_err());
    }

    #[test]
    fn the_imu_is_found_by_type_and_two_are_an_error_naming_them() {
        let topics = vec![
            t("/imu/temperature", "sensor_msgs/msg/Temperature"),
            t("/vn100/data", "sensor_msgs/msg/Imu"),
        ];
        assert_eq!(choose_imu(&topics, None).unwrap(), Some(1));
        let r = assign(&topics, &BagOptions::default()).unwrap();
        assert_eq!((r.imu, role_name(&r, 1).as_str()), (Some(1), "IMU"));
        let topics = vec![
            t("/imu0/data", "sensor_msgs/Imu"),
            t("/chatter", "std_msgs/String"),
            t("/imu1/data", "sensor_msgs/Imu"),
        ];
        let e = choose_imu(&topics, None).unwrap_err().to_string();
        assert!(
            e.contains("2 sensor_msgs/Imu topics")
                && e.contains("/imu0/data")
                && e.contains("/imu1/data")
                && e.contains("--imu-topic"),
            "{e}"
        );
        // Left for the reader to raise: a listing notes it.
        let r = assign(&topics, &BagOptions::default()).unwrap();
        assert_eq!(r.imu, None);
        assert!(
            r.notes.iter().any(|n| n.contains("--imu-topic")),
            "{:?}",
            r.notes
        );
        assert_eq!(choose_imu(&topics, Some("/imu1/data")).unwrap(), Some(2));
        let e = choose_imu(&topics, Some("/chatter"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("std_msgs/String"), "{e}");
        let named = BagOptions {
            imu_topic: Some("/imu2/data".into()),
            ..BagOptions::default()
        };
        let e = assign(&topics, &named).unwrap_err().to_string();
        assert!(e.contains("--imu-topic /imu2/data: no such topic"), "{e}");
        assert_eq!(choose_imu(&topics[1..2], None).unwrap(), None);
    }

    #[test]
    fn ros1_json_topic_is_the_dvl() {
        let topics = vec![
            t("/dvl/json_data", "std_msgs/String"),
            t("/dvl/data", "waterlinked_a50_ros_driver/DVL"),
            t("/rosout_agg", "rosgraph_msgs/Log"),
            t("/chatter", "std_msgs/String"),
        ];
        assert_eq!(choose_dvl(&topics, None).unwrap(), Some(0));
        assert_eq!(normalize_ok(), "sensor_msgs/Image");
    }

    fn normalize_ok() -> String {
        crate::io::bag::normalize_type("sensor_msgs/msg/Image")
    }
}
