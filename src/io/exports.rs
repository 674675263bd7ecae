//! The calibration in the forms other tools read: ROS static transform commands, a URDF robot
//! (the camera link, the DVL's and the IMU's links and the fixed joints to them), and a Kalibr
//! camchain-imucam file. One writer per format takes what a run calibrated ([`Export`]): the
//! DVL, an IMU, or both.
//!
//! A number in an export looks measured. A quantity the data did not determine (a lever arm held
//! at the default prior because the motion did not observe it, a parameter held at the value
//! given with `--init`, one the data constrained poorly) and a failed calibration exported with
//! `--force` are therefore said in each file, in a comment beside the numbers
//! ([`ExportNotes`]): `#` lines in the ROS commands and the Kalibr YAML, an XML comment in the
//! URDF.
//!
//! ROS's `static_transform_publisher` and a URDF joint take the pose of the child frame in the
//! parent frame, which for parent `cam0` and child `dvl` is `T_cam_dvl` (translation
//! `p_cam_dvl`, rotation `R_cam_dvl`). Kalibr's camchain-imucam file gives, per camera, the
//! camera's own calibration and `T_cam_imu` (IMU points into the camera frame) with
//! `timeshift_cam_imu` (`t_imu = t_cam + timeshift`). With a real IMU that slot holds the IMU
//! (`timeshift_cam_imu = -imu_time_offset_s`) and the DVL is under dvlcal's own keys
//! (`T_cam_dvl`, `timeshift_cam_dvl`), which Kalibr ignores; without one, the DVL is in the IMU's
//! place too, `T_cam_imu = T_camN_dvl` and `timeshift_cam_imu = -time_offset_s`.

use std::fmt::Write as _;

use nalgebra::{Matrix3, Matrix4};

use crate::error::{Error, Result};
use crate::io::calib_yaml::Observability;
use crate::lie::Se3;
use crate::types::CalibrationParams;

/// What the exports say beside numbers the data did not measure: for each quantity that a prior
/// or a given value determined, or that the data constrained poorly, one line saying so and why;
/// and the reasons of a calibration that failed its checks and was exported anyway. Empty
/// (the default) for a calibration whose every quantity the data determined.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExportNotes {
    /// The failure's reasons, when the calibration failed its checks (exported with `--force`).
    pub failed: Option<Vec<String>>,
    /// About the rotation of `T_cam_dvl`.
    pub rotation: Option<String>,
    /// About the lever arm (translation of `T_cam_dvl`).
    pub lever_arm: Option<String>,
    /// About the clock offset.
    pub time_offset: Option<String>,
    /// About the DVL velocity scale.
    pub velocity_scale: Option<String>,
}

impl ExportNotes {
    /// The note for a quantity in state `state`, with the reason the result gives for it;
    /// `None` for one the data determined well.
    pub fn note(state: Observability, reason: &str) -> Option<String> {
        let reason = reason.split_whitespace().collect::<Vec<_>>().join(" ");
        let why = if reason.is_empty() {
            String::new()
        } else {
            format!(": {reason}")
        };
        match state {
            Observability::Ok => None,
            Observability::Prior => Some(format!(
                "NOT MEASURED: the value is a prior's, not determined by the data{why}"
            )),
            // The reason only repeats how it was held.
            Observability::Fixed => Some(
                "NOT ESTIMATED: held at the value given with --init, not measured by this run"
                    .to_owned(),
            ),
            Observability::Weak => Some(format!(
                "POORLY DETERMINED: its standard deviation is above its limit{why}"
            )),
        }
    }

    /// Whether there is nothing to say.
    pub fn is_empty(&self) -> bool {
        *self == ExportNotes::default()
    }

    /// The notes as lines of text, each quantity named as the format names it (`names`:
    /// rotation, lever arm, clock offset, velocity scale), the failure first.
    fn lines(&self, names: [&str; 4]) -> Vec<String> {
        let mut v = Vec::new();
        if let Some(reasons) = &self.failed {
            let reasons: Vec<String> = reasons
                .iter()
                .map(|r| r.split_whitespace().collect::<Vec<_>>().join(" "))
                .collect();
            v.push(format!(
                "THIS CALIBRATION FAILED its checks and was written only because of --force; do \
                 not mount a DVL with it: {}",
                reasons.join("; ")
            ));
        }
        let notes = [
            &self.rotation,
            &self.lever_arm,
            &self.time_offset,
            &self.velocity_scale,
        ];
        for (name, note) in names.iter().zip(notes) {
            if let Some(n) = note {
                v.push(format!("{name}: {n}"));
            }
        }
        v
    }
}

/// `text` as the body of an XML comment, which may hold neither `--` nor end in `-`.
fn xml_comment_text(text: &str) -> String {
    let mut s = text.to_owned();
    while s.contains("--") {
        s = s.replace("--", "- -");
    }
    if s.ends_with('-') {
        s.push(' ');
    }
    s
}

/// Frame names used in the exports: the parent (camera) and child (DVL) of the transform.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameNames {
    /// Name of the camera frame, the parent of the transform (default `cam0`).
    pub camera: String,
    /// Name of the DVL frame, the child of the transform (default `dvl`).
    pub dvl: String,
}

impl Default for FrameNames {
    fn default() -> Self {
        FrameNames {
            camera: "cam0".into(),
            dvl: "dvl".into(),
        }
    }
}

impl FrameNames {
    /// The names `PARENT,CHILD` (as `--frames` takes them), checked with
    /// [`FrameNames::validate`].
    pub fn parse(text: &str) -> Result<FrameNames> {
        let Some((parent, child)) = text.split_once(',') else {
            return Err(Error::option(
                "--frames",
                format!("takes two frame names, PARENT,CHILD (as cam0,dvl); got '{text}'"),
            ));
        };
        let names = FrameNames {
            camera: parent.to_owned(),
            dvl: child.to_owned(),
        };
        names.validate()?;
        Ok(names)
    }

    /// Checks that both names are usable as ROS frame ids and in a URDF: not empty, no white
    /// space, commas, quotes or `<`, `>`, `&`, and different from each other.
    pub fn validate(&self) -> Result<()> {
        for (what, n) in [("parent", &self.camera), ("child", &self.dvl)] {
            if n.is_empty() {
                return Err(Error::option(
                    "--frames",
                    format!("the {what} frame name is empty"),
                ));
            }
            if let Some(c) = n
                .chars()
                .find(|c| c.is_whitespace() || c.is_control() || "<>&\"',".contains(*c))
            {
                return Err(Error::option(
                    "--frames",
                    format!("the {what} frame name '{n}' holds {c:?}, which a frame id may not"),
                ));
            }
        }
        if self.camera == self.dvl {
            return Err(Error::option(
                "--frames",
                format!("parent and child are both '{}'", self.camera),
            ));
        }
        Ok(())
    }
}

fn fmt_f(x: f64) -> String {
    // Enough digits to round-trip a double, no exponent noise for ordinary values.
    let s = format!("{x:.12}");
    let s = s.trim_end_matches('0');
    let s = s
        .strip_suffix('.')
        .map(|p| format!("{p}.0"))
        .unwrap_or(s.to_owned());
    if s == "-0.0" { "0.0".into() } else { s }
}

/// The sensor whose frame is the parent of the exports' transforms: the camera, or, for a DVL
/// calibrated against an IMU without a camera, the IMU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Parent {
    /// The camera (`T_cam_dvl`, `t_cam = t_dvl + offset`).
    #[default]
    Camera,
    /// The IMU (`T_imu_dvl`, `t_imu = t_dvl + offset`).
    Imu,
}

impl Parent {
    /// The sensor in words.
    fn noun(self) -> &'static str {
        match self {
            Parent::Camera => "camera",
            Parent::Imu => "IMU",
        }
    }

    /// The subscript of its frame and clock (`T_cam_dvl`, `t_cam`).
    fn sub(self) -> &'static str {
        match self {
            Parent::Camera => "cam",
            Parent::Imu => "imu",
        }
    }
}

/// What the exports write: the DVL's calibration, the IMU's, or both, with the frames' names and
/// what the exports say beside the DVL's numbers. A run of the DVL alone has `imu: None`; a run
/// of the camera and an IMU alone has `dvl: None`; a DVL calibrated against an IMU without a
/// camera has `parent: Parent::Imu`, its `T_imu_dvl` in `dvl` and no `imu`.
#[derive(Clone, Copy, Debug)]
pub struct Export<'a> {
    /// The DVL's calibration (`T_cam_dvl`, its clock offset and velocity scale; `T_imu_dvl`
    /// and the IMU's clock when `parent` is the IMU).
    pub dvl: Option<&'a CalibrationParams>,
    /// The IMU calibrated against the camera (its frame named in it).
    pub imu: Option<&'a ImuExport>,
    /// The parent's frame (`names.camera`, whichever sensor `parent` is) and the DVL's.
    pub names: &'a FrameNames,
    /// What the DVL's numbers do not measure, and a failure's reasons.
    pub notes: &'a ExportNotes,
    /// The sensor of the parent frame.
    pub parent: Parent,
}

impl<'a> Export<'a> {
    /// The DVL's calibration alone.
    pub fn dvl(c: &'a CalibrationParams, names: &'a FrameNames, notes: &'a ExportNotes) -> Self {
        Export {
            dvl: Some(c),
            imu: None,
            names,
            notes,
            parent: Parent::Camera,
        }
    }

    /// A DVL calibrated against an IMU (no camera): `c.t_cam_dvl` holds `T_imu_dvl` and its
    /// clock offset `t_imu = t_dvl + offset`; `names.camera` is the IMU's frame.
    pub fn dvl_in_imu(
        c: &'a CalibrationParams,
        names: &'a FrameNames,
        notes: &'a ExportNotes,
    ) -> Self {
        Export {
            parent: Parent::Imu,
            ..Export::dvl(c, names, notes)
        }
    }

    /// The same with `imu` beside it.
    pub fn with_imu(self, imu: Option<&'a ImuExport>) -> Self {
        Export { imu, ..self }
    }
}

/// An IMU calibrated against the camera, for the exports: its transform, clock offset and
/// frame.
#[derive(Clone, Debug)]
pub struct ImuExport {
    /// `T_cam_imu` (camera 0): maps IMU-frame points into the camera frame.
    pub t_cam_imu: Se3,
    /// `t_cam = t_imu + time_offset_s`.
    pub time_offset_s: f64,
    /// The IMU frame's name (`imu`).
    pub frame: String,
}

/// The ROS 1 and ROS 2 commands publishing `t` (the pose of `child` in `parent`) as a static
/// transform, the ROS 2 one after a comment line.
fn tf_commands(s: &mut String, t: &Se3, parent: &str, child: &str) {
    let (p, q) = (t.trans, t.quaternion_xyzw());
    let [x, y, z, qx, qy, qz, qw] = [p.x, p.y, p.z, q[0], q[1], q[2], q[3]].map(fmt_f);
    let _ = writeln!(
        s,
        "rosrun tf2_ros static_transform_publisher {x} {y} {z} {qx} {qy} {qz} {qw} {parent} {child}"
    );
    let _ = writeln!(s, "# ROS 2 (tf2_ros)");
    let _ = writeln!(
        s,
        "ros2 run tf2_ros static_transform_publisher --x {x} --y {y} --z {z} --qx {qx} --qy {qy} \
         --qz {qz} --qw {qw} --frame-id {parent} --child-frame-id {child}"
    );
}

/// The ROS 1 and ROS 2 command lines publishing `T_cam_dvl` and `T_cam_imu` (each present) as
/// static transforms, one per line, each preceded by a comment line and followed by the
/// sensor's clock; `notes` first, as `#` lines.
pub fn ros_static_transform(e: &Export) -> String {
    let mut s = String::new();
    for l in e.notes.lines([
        "rotation (qx qy qz qw)",
        "lever arm (x y z)",
        "clock offset",
        "DVL velocity scale",
    ]) {
        let _ = writeln!(s, "# {l}");
    }
    let camera = &e.names.camera;
    if let Some(c) = e.dvl {
        let _ = writeln!(
            s,
            "# ROS 1 (tf2_ros): x y z qx qy qz qw parent child; the DVL frame in the {} frame",
            e.parent.noun()
        );
        tf_commands(&mut s, &c.t_cam_dvl, camera, &e.names.dvl);
        let _ = writeln!(
            s,
            "# clock: t_{} = t_dvl + {} s; DVL velocity scale {}",
            e.parent.sub(),
            fmt_f(c.time_offset_s),
            fmt_f(c.velocity_scale)
        );
    }
    if let Some(imu) = e.imu {
        let _ = writeln!(
            s,
            "# The IMU frame in the camera frame (T_cam_imu). ROS 1 (tf2_ros)"
        );
        tf_commands(&mut s, &imu.t_cam_imu, camera, &imu.frame);
        let _ = writeln!(s, "# clock: t_cam = t_imu + {} s", fmt_f(imu.time_offset_s));
    }
    s
}

fn matrix_rows(s: &mut String, indent: &str, m: &Matrix4<f64>) {
    for r in 0..4 {
        let _ = writeln!(
            s,
            "{indent}- [{}, {}, {}, {}]",
            fmt_f(m[(r, 0)]),
            fmt_f(m[(r, 1)]),
            fmt_f(m[(r, 2)]),
            fmt_f(m[(r, 3)])
        );
    }
}

/// One camera of the chain, as the camchain-imucam file gives it.
#[derive(Clone, Debug)]
pub struct KalibrCamera {
    /// The camera's keys of Kalibr's camchain (intrinsics, distortion, resolution, `T_cn_cnm1`
    /// for all but cam0, `rostopic` when known), one per line, indented by two spaces; empty
    /// when the camera's calibration is unknown (poses from elsewhere).
    pub entry: String,
    /// `T_cn_c0`: maps cam0 points into this camera (identity for cam0).
    pub t_cn_c0: Matrix4<f64>,
    /// The other cameras that see the same scene (Kalibr's `cam_overlaps`).
    pub overlaps: Vec<usize>,
}

/// The comment at the top of the camchain-imucam file: what `T_cam_imu` holds and where the DVL
/// is.
fn kalibr_header(e: &Export) -> String {
    let version = env!("CARGO_PKG_VERSION");
    let names = e.names;
    let dvl_keys = format!(
        "# dvl_velocity_scale: v_dvl = scale * R_dvl_cam * v_cam(DVL origin). Frames: {} (camera),\n\
         # {} (DVL).",
        names.camera, names.dvl
    );
    match (e.dvl, e.imu) {
        (_, None) => format!(
            "# dvlcal {version}: camera chain and DVL in the form of Kalibr's camchain-imucam.yaml, \
             the DVL\n\
             # in the IMU's place. T_cam_imu = T_cam_dvl maps DVL-frame points into camera n;\n\
             # timeshift_cam_imu = timeshift_cam_dvl: t_dvl = t_cam + timeshift (= \
             -time_offset_s).\n{dvl_keys}"
        ),
        (Some(_), Some(imu)) => format!(
            "# dvlcal {version}: camera chain, IMU and DVL in the form of Kalibr's \
             camchain-imucam.yaml.\n\
             # T_cam_imu maps IMU-frame points into camera n, timeshift_cam_imu: t_imu = t_cam +\n\
             # timeshift (= -imu_time_offset_s). The DVL is under T_cam_dvl and timeshift_cam_dvl\n\
             # (t_dvl = t_cam + timeshift = t_cam - time_offset_s), which Kalibr's readers \
             ignore.\n\
             # IMU frame: {}.\n{dvl_keys}",
            imu.frame
        ),
        (None, Some(imu)) => format!(
            "# dvlcal {version}: camera chain and IMU in the form of Kalibr's \
             camchain-imucam.yaml.\n\
             # T_cam_imu maps IMU-frame points into camera n, timeshift_cam_imu: t_imu = t_cam +\n\
             # timeshift (= -imu_time_offset_s). Frames: {} (camera), {} (IMU).",
            names.camera, imu.frame
        ),
    }
}

/// A Kalibr camchain-imucam file: for each camera `n` its camchain keys, `cam_overlaps`,
/// `T_cam_imu` (IMU points into camera n) and `timeshift_cam_imu` (`t_imu = t_cam +
/// timeshift`), then the DVL under dvlcal's explicit names (`T_cam_dvl`, `timeshift_cam_dvl`:
/// `t_dvl = t_cam + timeshift`, so `-time_offset_s`), the DVL velocity scale and the DVL's frame
/// name. With an IMU, Kalibr's IMU keys hold the IMU (`T_camn_imu`, `-imu_time_offset_s`) and
/// the DVL is under its own keys alone, which Kalibr's readers ignore; without one, the DVL is
/// in the IMU's place as well (`T_cam_imu = T_camn_dvl`). Without a DVL, the IMU's keys alone.
/// Kalibr's readers count the cameras as the file's top-level keys, so everything lives under
/// `camN`. A camera with an empty `entry` is written with the transforms alone and a comment
/// saying its calibration is unknown. `notes` come after the header as `#` lines, and each
/// camera's transforms are preceded by a comment pointing at them.
pub fn kalibr_camchain_imucam(e: &Export, cams: &[KalibrCamera]) -> String {
    let mut s = kalibr_header(e);
    s.push('\n');
    if cams.iter().any(|k| k.entry.is_empty()) {
        let whose = match (e.dvl, e.imu) {
            (_, None) => "DVL's",
            (None, Some(_)) => "IMU's",
            (Some(_), Some(_)) => "IMU's and DVL's",
        };
        let _ = writeln!(
            s,
            "# The camera poses came from elsewhere: the camera's intrinsics and distortion are \
             unknown\n# here, so this file gives only the {whose} transform and time shift; add \
             the camera's\n# Kalibr keys (camera_model, intrinsics, ...) before a Kalibr-based \
             tool reads it."
        );
    }
    let note_lines = e.notes.lines(if e.imu.is_some() {
        [
            "DVL rotation (upper-left 3x3 of T_cam_dvl)",
            "DVL lever arm (last column of T_cam_dvl)",
            "DVL clock offset (timeshift_cam_dvl)",
            "DVL velocity scale (dvl_velocity_scale)",
        ]
    } else {
        [
            "rotation (upper-left 3x3 of T_cam_imu and T_cam_dvl)",
            "lever arm (last column of T_cam_imu and T_cam_dvl)",
            "clock offset (timeshift_cam_imu, timeshift_cam_dvl)",
            "DVL velocity scale (dvl_velocity_scale)",
        ]
    });
    for l in &note_lines {
        let _ = writeln!(s, "# {l}");
    }
    // Kalibr's IMU slot: the IMU's transform and time shift, or the DVL's in its place.
    let slot = e
        .imu
        .map(|i| (&i.t_cam_imu, i.time_offset_s))
        .or(e.dvl.map(|c| (&c.t_cam_dvl, c.time_offset_s)));
    for (n, cam) in cams.iter().enumerate() {
        let _ = writeln!(s, "cam{n}:");
        s.push_str(&cam.entry);
        let overlaps: Vec<String> = cam.overlaps.iter().map(|o| o.to_string()).collect();
        let _ = writeln!(s, "  cam_overlaps: [{}]", overlaps.join(", "));
        if !note_lines.is_empty() {
            let _ = writeln!(
                s,
                "  # not all of the values below were measured: see the notes at the top"
            );
        }
        let mut transform = |key: &str, t: &Se3, offset_s: f64| {
            let _ = writeln!(s, "  T_cam_{key}:");
            matrix_rows(&mut s, "  ", &(cam.t_cn_c0 * t.to_matrix()));
            let _ = writeln!(s, "  timeshift_cam_{key}: {}", fmt_f(-offset_s));
        };
        if let Some((t, offset_s)) = slot {
            transform("imu", t, offset_s);
        }
        if let Some(c) = e.dvl {
            transform("dvl", &c.t_cam_dvl, c.time_offset_s);
            let _ = writeln!(s, "  dvl_velocity_scale: {}", fmt_f(c.velocity_scale));
            let _ = writeln!(s, "  dvl_frame_id: {}", e.names.dvl);
        }
    }
    s
}

/// Roll, pitch and yaw (radians) of `r` in URDF's and ROS's convention: rotations about the
/// fixed x, y and z axes in that order, `R = Rz(yaw) Ry(pitch) Rx(roll)`; pitch in
/// [-pi/2, pi/2]. At gimbal lock (pitch +-pi/2) only roll -+ yaw is defined: roll is set to 0.
pub fn rpy_from_rotation(r: &Matrix3<f64>) -> [f64; 3] {
    // cos(pitch) from the first column's other entries: accurate also near the lock, where
    // sqrt(1 - sin^2) would lose digits.
    let cp = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cp);
    if cp > 1e-12 {
        [
            r[(2, 1)].atan2(r[(2, 2)]),
            pitch,
            r[(1, 0)].atan2(r[(0, 0)]),
        ]
    } else {
        // R = Rz(yaw) Ry(+-pi/2) Rx(roll) depends on roll -+ yaw only; with roll 0 its second
        // column is (-sin yaw, cos yaw, 0).
        [0.0, pitch, (-r[(0, 1)]).atan2(r[(1, 1)])]
    }
}

/// The link `child` and the fixed joint `PARENT_to_CHILD` that places it at `t` in `parent`,
/// with `comments` above the origin.
fn urdf_joint(s: &mut String, parent: &str, child: &str, t: &Se3, comments: &[String]) {
    let [roll, pitch, yaw] = rpy_from_rotation(&t.rot).map(fmt_f);
    let _ = writeln!(s, "  <link name=\"{child}\"/>");
    let _ = writeln!(s, "  <joint name=\"{parent}_to_{child}\" type=\"fixed\">");
    let _ = writeln!(s, "    <parent link=\"{parent}\"/>");
    let _ = writeln!(s, "    <child link=\"{child}\"/>");
    for c in comments {
        let _ = writeln!(s, "    <!-- {} -->", xml_comment_text(c));
    }
    let _ = writeln!(
        s,
        "    <origin xyz=\"{} {} {}\" rpy=\"{roll} {pitch} {yaw}\"/>",
        fmt_f(t.trans.x),
        fmt_f(t.trans.y),
        fmt_f(t.trans.z)
    );
    let _ = writeln!(s, "  </joint>");
}

/// A URDF robot of the camera link (parent) and the DVL's and the IMU's links (each present),
/// each child on a fixed joint `PARENT_to_CHILD`, as ROS's URDF parsers read a file: the DVL's
/// `<origin xyz rpy>` is `T_cam_dvl`, the IMU's `T_cam_imu`, rpy as [`rpy_from_rotation`]. The
/// clock offsets and the DVL's scale, which a URDF cannot hold, are given in comments, and
/// `notes` in a comment above the DVL's origin (above the IMU's without a DVL). To add the
/// sensors to a robot's own URDF, copy their links and joints (the parent link is the robot's
/// camera).
pub fn urdf_robot(e: &Export) -> String {
    let parent = &e.names.camera;
    let mut s = String::new();
    let _ = writeln!(s, "<?xml version=\"1.0\"?>");
    let convention = "rpy = fixed-axis roll about x, then pitch about y, then yaw about z (R = \
                      Rz(yaw) Ry(pitch) Rx(roll)), rad.";
    let version = env!("CARGO_PKG_VERSION");
    let child = match (e.dvl, e.imu) {
        (Some(c), _) => {
            let child = &e.names.dvl;
            let (noun, sub) = (e.parent.noun(), e.parent.sub());
            let _ = writeln!(
                s,
                "<!-- dvlcal {version}: the DVL frame in the {noun} frame (T_{sub}_dvl); \
                 {convention}\n     Clock: t_{sub} = t_dvl + {} s; DVL velocity scale {}.\n     \
                 To add the DVL to a robot's URDF, copy the link {child} and the joint; {parent} \
                 is the robot's {noun} link. -->",
                fmt_f(c.time_offset_s),
                fmt_f(c.velocity_scale)
            );
            child
        }
        (None, Some(imu)) => {
            let child = &imu.frame;
            let _ = writeln!(
                s,
                "<!-- dvlcal {version}: the IMU frame in the camera frame (T_cam_imu); \
                 {convention}\n     Clock: t_cam = t_imu + {} s.\n     \
                 To add the IMU to a robot's URDF, copy the link {child} and the joint; {parent} \
                 is the robot's camera link. -->",
                fmt_f(imu.time_offset_s)
            );
            child
        }
        (None, None) => &e.names.dvl,
    };
    let _ = writeln!(s, "<robot name=\"{parent}_{child}_calibration\">");
    let _ = writeln!(s, "  <link name=\"{parent}\"/>");
    let notes = e.notes.lines([
        "rotation (origin rpy)",
        "lever arm (origin xyz)",
        "clock offset",
        "DVL velocity scale",
    ]);
    if let Some(c) = e.dvl {
        urdf_joint(&mut s, parent, &e.names.dvl, &c.t_cam_dvl, &notes);
    }
    if let Some(imu) = e.imu {
        let mut comments = vec![format!(
            "T_cam_imu; clock: t_cam = t_imu + {} s",
            fmt_f(imu.time_offset_s)
        )];
        if e.dvl.is_none() {
            comments.extend(notes);
        }
        urdf_joint(&mut s, parent, &imu.frame, &imu.t_cam_imu, &comments);
    }
    let _ = writeln!(s, "</robot>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;
    use nalgebra::{Matrix3, Vector3, Vector6};

    fn params() -> CalibrationParams {
        CalibrationParams {
            t_cam_dvl: Se3::exp(&Vector6::new(0.1, -0.2, 0.3, 0.4, -0.5, 0.6)),
            time_offset_s: 0.125,
            velocity_scale: 1.01,
        }
    }

    #[test]
    fn ros_line_carries_the_pose_of_the_dvl_in_the_camera() {
        let c = params();
        let (names, notes) = (FrameNames::default(), ExportNotes::default());
        let text = ros_static_transform(&Export::dvl(&c, &names, &notes));
        let line = text
            .lines()
            .find(|l| l.starts_with("rosrun"))
            .unwrap_or_default();
        let nums: Vec<f64> = line
            .split_whitespace()
            .skip(3)
            .take(7)
            .filter_map(|x| x.parse().ok())
            .collect();
        assert_eq!(nums.len(), 7, "{line}");
        let back = Se3::from_quaternion_xyzw(
            &[nums[3], nums[4], nums[5], nums[6]],
            Vector3::new(nums[0], nums[1], nums[2]),
        );
        let d = (back.inverse() * c.t_cam_dvl).log().norm();
        assert!(d < 1e-10, "round trip off by {d}");
        assert!(line.ends_with("cam0 dvl"));
        assert!(text.contains("--frame-id cam0 --child-frame-id dvl"));
    }

    fn matrix_of(v: &serde_yaml::Value) -> Matrix4<f64> {
        let mut m = Matrix4::from_element(f64::NAN);
        for (r, row) in v.as_sequence().into_iter().flatten().enumerate() {
            for (k, x) in row.as_sequence().into_iter().flatten().enumerate() {
                m[(r, k)] = x.as_f64().unwrap_or(f64::NAN);
            }
        }
        m
    }

    #[test]
    fn camchain_imucam_composes_the_stereo_extrinsics_and_negates_the_offset() {
        let c = params();
        let t_c1_c0 = Se3::new(nalgebra::Matrix3::identity(), Vector3::new(-0.12, 0.0, 0.0));
        let cams = [
            KalibrCamera {
                entry: "  camera_model: pinhole\n".into(),
                t_cn_c0: Matrix4::identity(),
                overlaps: vec![1],
            },
            KalibrCamera {
                entry: String::new(),
                t_cn_c0: t_c1_c0.to_matrix(),
                overlaps: vec![0],
            },
        ];
        let (names, notes) = (FrameNames::default(), ExportNotes::default());
        let text = kalibr_camchain_imucam(&Export::dvl(&c, &names, &notes), &cams);
        let v: serde_yaml::Value = serde_yaml::from_str(&text).expect("valid YAML");
        // Kalibr counts the cameras as the top-level keys: nothing else may be there.
        let keys: Vec<&str> = v
            .as_mapping()
            .into_iter()
            .flatten()
            .filter_map(|(k, _)| k.as_str())
            .collect();
        assert_eq!(keys, ["cam0", "cam1"]);
        for (cam, t) in [("cam0", Matrix4::identity()), ("cam1", t_c1_c0.to_matrix())] {
            let want = t * c.t_cam_dvl.to_matrix();
            for key in ["T_cam_imu", "T_cam_dvl"] {
                let d = (matrix_of(&v[cam][key]) - want).abs().max();
                assert!(d < 1e-11, "{cam} {key} off by {d}");
            }
            assert_eq!(v[cam]["timeshift_cam_imu"].as_f64(), Some(-0.125));
            assert_eq!(v[cam]["timeshift_cam_dvl"].as_f64(), Some(-0.125));
            assert_eq!(v[cam]["dvl_velocity_scale"].as_f64(), Some(1.01));
        }
        assert_eq!(v["cam0"]["camera_model"].as_str(), Some("pinhole"));
        assert_eq!(v["cam1"]["cam_overlaps"][0].as_u64(), Some(0));
        // A camera without its calibration is said to lack it.
        assert!(
            text.contains("intrinsics and distortion are unknown"),
            "{text}"
        );
    }

    fn imu() -> ImuExport {
        ImuExport {
            t_cam_imu: Se3::exp(&Vector6::new(0.02, 0.05, -0.01, -1.2, 0.3, 1.6)),
            time_offset_s: -0.0375,
            frame: "imu".into(),
        }
    }

    /// A stereo chain with both cameras' keys: cam1 12 cm beside cam0.
    fn stereo() -> Vec<KalibrCamera> {
        let t_c1_c0 = Se3::new(Matrix3::identity(), Vector3::new(-0.12, 0.0, 0.0));
        vec![
            KalibrCamera {
                entry: "  camera_model: pinhole\n  intrinsics: [460.0, 459.5, 367.0, 248.0]\n"
                    .into(),
                t_cn_c0: Matrix4::identity(),
                overlaps: vec![1],
            },
            KalibrCamera {
                entry: "  camera_model: pinhole\n  intrinsics: [457.0, 456.0, 379.0, 255.0]\n"
                    .into(),
                t_cn_c0: t_c1_c0.to_matrix(),
                overlaps: vec![0],
            },
        ]
    }

    /// The DVL and an IMU: ROS commands, URDF and Kalibr file byte for byte as the writers that
    /// added the IMU to the DVL's finished text wrote them (tests/fixtures/exports_imu, with
    /// `VERSION` for the version).
    #[test]
    fn with_the_dvl_the_imus_exports_are_what_they_were() {
        let golden = |text: &str| {
            text.replace(
                "dvlcal VERSION:",
                &format!("dvlcal {}:", env!("CARGO_PKG_VERSION")),
            )
        };
        let (c, imu) = (params(), imu());
        let names = FrameNames::parse("camera_link,dvl_link").unwrap();
        let notes = ExportNotes::default();
        let e = Export::dvl(&c, &names, &notes).with_imu(Some(&imu));
        assert_eq!(
            ros_static_transform(&e),
            golden(include_str!("../../tests/fixtures/exports_imu/tf.txt"))
        );
        assert_eq!(
            urdf_robot(&e),
            golden(include_str!("../../tests/fixtures/exports_imu/urdf.xml"))
        );
        assert_eq!(
            kalibr_camchain_imucam(&e, &stereo()),
            golden(include_str!(
                "../../tests/fixtures/exports_imu/camchain-imucam.yaml"
            ))
        );
    }

    /// The camera and an IMU without a DVL: the Kalibr file parses, holds the two cameras as
    /// its only top-level keys, each with the IMU in Kalibr's IMU keys (composed with the
    /// camera's `T_cn_c0`, the time shift `-imu_time_offset_s`) and no DVL key; the URDF is a
    /// robot `check_urdf` (Debian's liburdfdom-tools) reads with the IMU as the camera's one
    /// child; the ROS commands publish the IMU alone.
    #[test]
    fn without_a_dvl_the_exports_hold_the_imu_alone_and_parse() {
        let imu = imu();
        let (names, notes) = (FrameNames::default(), ExportNotes::default());
        let e = Export {
            dvl: None,
            imu: Some(&imu),
            names: &names,
            notes: &notes,
            parent: Parent::Camera,
        };
        let cams = stereo();
        let text = kalibr_camchain_imucam(&e, &cams);
        let v: serde_yaml::Value = serde_yaml::from_str(&text).expect("valid YAML");
        let keys = |v: &serde_yaml::Value| -> Vec<String> {
            v.as_mapping()
                .into_iter()
                .flatten()
                .filter_map(|(k, _)| k.as_str().map(String::from))
                .collect()
        };
        assert_eq!(keys(&v), ["cam0", "cam1"]);
        for (n, cam) in ["cam0", "cam1"].into_iter().enumerate() {
            let want = cams[n].t_cn_c0 * imu.t_cam_imu.to_matrix();
            let d = (matrix_of(&v[cam]["T_cam_imu"]) - want).abs().max();
            assert!(d < 1e-11, "{cam} T_cam_imu off by {d}");
            assert_eq!(v[cam]["timeshift_cam_imu"].as_f64(), Some(0.0375));
            assert!(!keys(&v[cam]).iter().any(|k| k.contains("dvl")), "{text}");
        }
        assert!(!text.contains("DVL"), "{text}");

        let urdf =
            std::env::temp_dir().join(format!("dvlcal-imu-only-urdf-{}.xml", std::process::id()));
        std::fs::write(&urdf, urdf_robot(&e)).unwrap();
        let r = std::process::Command::new("check_urdf")
            .arg(&urdf)
            .output()
            .expect("check_urdf (Debian's liburdfdom-tools) runs");
        let _ = std::fs::remove_file(&urdf);
        let parsed = String::from_utf8_lossy(&r.stdout);
        assert!(r.status.success(), "{parsed}");
        assert!(
            parsed.contains("root Link: cam0 has 1 child(ren)")
                && parsed.contains("child(1):  imu"),
            "{parsed}"
        );

        let tf = ros_static_transform(&e);
        assert_eq!(tf.matches("rosrun").count(), 1, "{tf}");
        assert!(tf.contains("--frame-id cam0 --child-frame-id imu"), "{tf}");
        assert!(tf.contains("# clock: t_cam = t_imu + -0.0375 s"), "{tf}");
    }

    /// R = Rz(yaw) Ry(pitch) Rx(roll) written out entry by entry (URDF's definition), not
    /// through the crate's own rotation code.
    fn zyx(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sy, cy) = yaw.sin_cos();
        Matrix3::new(
            cy * cp,
            cy * sp * sr - sy * cr,
            cy * sp * cr + sy * sr,
            sy * cp,
            sy * sp * sr + cy * cr,
            sy * sp * cr - cy * sr,
            -sp,
            cp * sr,
            cp * cr,
        )
    }

    #[test]
    fn urdf_rpy_matches_hand_derived_rotations() {
        use std::f64::consts::FRAC_PI_2;
        let close = |a: [f64; 3], b: [f64; 3], tol: f64| {
            assert!(
                a.iter().zip(&b).all(|(x, y)| (x - y).abs() < tol),
                "{a:?} against {b:?}"
            );
        };
        // REP 103's camera optical frame in a body frame: z forward = body x, x right = body -y,
        // y down = body -z; its well-known rpy is (-pi/2, 0, -pi/2).
        let optical = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        close(
            rpy_from_rotation(&optical),
            [-FRAC_PI_2, 0.0, -FRAC_PI_2],
            1e-15,
        );
        // A yaw of 30 degrees alone.
        let (s, c) = (0.5, 3f64.sqrt() / 2.0);
        let yaw = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        close(
            rpy_from_rotation(&yaw),
            [0.0, 0.0, 30f64.to_radians()],
            1e-15,
        );
        // Gimbal lock: pitch +90 degrees with a yaw of 0.3 rad; only roll - yaw is defined, and
        // roll is reported as 0. R = Rz(0.3) Ry(pi/2) = [[0, -s, c], [0, c, s], [-1, 0, 0]].
        let (s, c) = 0.3f64.sin_cos();
        let lock = Matrix3::new(0.0, -s, c, 0.0, c, s, -1.0, 0.0, 0.0);
        close(rpy_from_rotation(&lock), [0.0, FRAC_PI_2, 0.3], 1e-15);
        // Pitch -90 degrees: R = Rz(0.3) Ry(-pi/2) = [[0, -s, -c], [0, c, -s], [1, 0, 0]].
        let lock = Matrix3::new(0.0, -s, -c, 0.0, c, -s, 1.0, 0.0, 0.0);
        close(rpy_from_rotation(&lock), [0.0, -FRAC_PI_2, 0.3], 1e-15);
        // Near the lock every angle is still recovered.
        for (r, p, y) in [
            (0.2, FRAC_PI_2 - 1e-6, 0.3),
            (-2.5, -FRAC_PI_2 + 1e-5, 3.0),
            (1.0, 0.7, -2.0),
            (3.1, -0.2, 0.1),
        ] {
            close(rpy_from_rotation(&zyx(r, p, y)), [r, p, y], 1e-9);
        }
        // The joint's origin carries those angles and the lever arm.
        let c = CalibrationParams {
            t_cam_dvl: Se3::new(optical, Vector3::new(0.1, -0.2, 0.3)),
            time_offset_s: 0.0,
            velocity_scale: 1.0,
        };
        let names = FrameNames::parse("camera_link,dvl_link").unwrap();
        let notes = ExportNotes::default();
        let x = urdf_robot(&Export::dvl(&c, &names, &notes));
        assert!(x.contains("<parent link=\"camera_link\"/>"), "{x}");
        assert!(x.contains("<child link=\"dvl_link\"/>"), "{x}");
        assert!(
            x.contains(
                "<origin xyz=\"0.1 -0.2 0.3\" rpy=\"-1.570796326795 0.0 -1.570796326795\"/>"
            ),
            "{x}"
        );
    }

    #[test]
    fn frame_names_are_checked() {
        let ok = FrameNames::parse("base_link,dvl").unwrap();
        assert_eq!((ok.camera.as_str(), ok.dvl.as_str()), ("base_link", "dvl"));
        for bad in [
            "cam0",
            ",dvl",
            "cam0,",
            "cam 0,dvl",
            "cam0,dv\tl",
            "cam0,a<b",
            "dvl,dvl",
        ] {
            let e = FrameNames::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--frames"), "{bad}: {e}");
        }
    }

    #[test]
    fn xml_comments_hold_no_double_hyphen() {
        assert_eq!(
            xml_comment_text("give --lever-arm-prior"),
            "give - -lever-arm-prior"
        );
        assert_eq!(xml_comment_text("a --- b -"), "a - - - b - ");
        assert!(!xml_comment_text("----").contains("--"));
    }

    #[test]
    fn numbers_print_plainly() {
        assert_eq!(fmt_f(1.0), "1.0");
        assert_eq!(fmt_f(-0.0), "0.0");
        assert_eq!(fmt_f(0.125), "0.125");
        assert_eq!(fmt_f(-2.5e-13), "0.0");
    }
}
