//! The camera's poses from a bag's pose topic: `geometry_msgs/PoseStamped`,
//! `PoseWithCovarianceStamped`, `TransformStamped`, `nav_msgs/Odometry`, or the transforms of
//! one child frame in `tf2_msgs/TFMessage`.

use std::collections::BTreeMap;

use nalgebra::Matrix6;

use crate::error::{Error, Result};
use crate::io::bag::cdr;
use crate::io::bag::open::{LISTED, OpenBag, message_time};
use crate::io::bag::roles::{self, Kind};
use crate::io::images::raw_time;
use crate::lie::Se3;
use crate::time::Epoch;
use crate::types::PoseMeasurement;

/// What reading a pose topic found.
#[derive(Clone, Debug, Default)]
pub struct BagPoses {
    /// The epoch of the pose times: the whole second of the first pose.
    pub epoch: Epoch,
    /// The poses `T_world_cam`, in time order, with the messages' covariances (converted by
    /// [`ros_pose_covariance`]) when every pose carries a usable one, else without.
    pub poses: Vec<PoseMeasurement>,
    /// Whether the poses carry the messages' covariances.
    pub covariances: bool,
    /// The topic (and, for TF, the child frame) read.
    pub source: String,
    /// Things the user should know (zero stamps, repeated stamps, skipped messages).
    pub warnings: Vec<String>,
}

/// The camera's poses from the bag's pose topic (`geometry_msgs/PoseStamped`,
/// `PoseWithCovarianceStamped`, `TransformStamped`, `nav_msgs/Odometry`, or the transforms of
/// one child frame in `tf2_msgs/TFMessage`): `T_parent_child` read as `T_world_cam`.
pub fn read_bag_poses(ob: &OpenBag) -> Result<BagPoses> {
    let Some(idx) = ob.roles.pose else {
        return Err(Error::Input(format!(
            "{}: no image or pose topic in this bag (topics: {}); choose one with \
             --image-topics or --pose-topic",
            ob.path().display(),
            ob.topic_list()
        )));
    };
    let topic = ob.topic(idx).clone();
    let Some(kind) = roles::kind(&topic) else {
        return Err(Error::Input(format!(
            "{}: {} is not a pose topic",
            ob.path().display(),
            topic.name
        )));
    };
    let ser = topic.serialization;
    let want_frame = ob
        .options
        .pose_frame
        .as_deref()
        .map(|f| f.trim_start_matches('/').to_string());
    // Per child frame (one, "", for the topics of one pose per message): (t_ns, pose).
    let mut by_child: BTreeMap<String, Vec<Stamped>> = BTreeMap::new();
    let mut zero = 0usize;
    let mut bad = Vec::new();
    let mut n_bad = 0usize;
    let time = ob.options.time;
    let summary = ob.bag.messages(&|i| i == idx, &mut |m| {
        let decoded: Result<Vec<Decoded>> = (|| {
            Ok(match kind {
                Kind::PoseStamped => {
                    let p: cdr::PoseStamped = cdr::decode(m.data, ser)?;
                    vec![(String::new(), p.header.stamp, p.pose, None)]
                }
                Kind::PoseCov => {
                    let p: cdr::PoseWithCovarianceStamped = cdr::decode(m.data, ser)?;
                    vec![(
                        String::new(),
                        p.header.stamp,
                        p.pose.pose,
                        Some(p.pose.covariance),
                    )]
                }
                Kind::Odometry => {
                    let p: cdr::Odometry = cdr::decode(m.data, ser)?;
                    vec![(
                        String::new(),
                        p.header.stamp,
                        p.pose.pose,
                        Some(p.pose.covariance),
                    )]
                }
                Kind::Transform => {
                    let t: cdr::TransformStamped = cdr::decode(m.data, ser)?;
                    vec![transform_pose(&t)]
                }
                Kind::Tf => {
                    let tf: cdr::TfMessage = cdr::decode(m.data, ser)?;
                    tf.transforms.iter().map(transform_pose).collect()
                }
                _ => Vec::new(),
            })
        })();
        match decoded {
            Ok(list) => {
                for (child, stamp, pose, cov) in list {
                    let t_ns = message_time(stamp.as_nanos(), m.log_time_ns, time, &mut zero);
                    match se3_of(&pose) {
                        Some(p) => by_child.entry(child).or_default().push((t_ns, p, cov)),
                        None => {
                            n_bad += 1;
                            if bad.len() < LISTED {
                                bad.push(format!(
                                    "{} message {}: not a pose (quaternion of norm far from 1, \
                                     or a value that is not finite)",
                                    topic.name, m.index
                                ));
                            }
                        }
                    }
                }
            }
            Err(e) => {
                n_bad += 1;
                if bad.len() < LISTED {
                    bad.push(format!("{} message {}: {e}", topic.name, m.index));
                }
            }
        }
        Ok(())
    })?;
    let mut warnings: Vec<String> = summary
        .problems
        .iter()
        .map(|p| format!("{}: {p}", ob.path().display()))
        .collect();
    let (child, mut list) = if kind == Kind::Tf || kind == Kind::Transform {
        let children: Vec<&String> = by_child.keys().collect();
        let chosen = match &want_frame {
            Some(f) => by_child.keys().find(|k| *k == f).cloned().ok_or_else(|| {
                Error::Input(format!(
                    "{}: no transform to child frame {f} on {} (child frames: {})",
                    ob.path().display(),
                    topic.name,
                    join(&children)
                ))
            })?,
            None if children.len() == 1 => children[0].clone(),
            None => {
                return Err(Error::Input(format!(
                    "{}: {} holds transforms to several child frames ({}); choose the \
                     camera's with --pose-frame",
                    ob.path().display(),
                    topic.name,
                    join(&children)
                )));
            }
        };
        let list = by_child.remove(&chosen).unwrap_or_default();
        (chosen, list)
    } else {
        (String::new(), by_child.remove("").unwrap_or_default())
    };
    if n_bad > 0 {
        warnings.push(format!(
            "{n_bad} messages of {} could not be used: {}",
            topic.name,
            bad.join("; ")
        ));
    }
    if zero > 0 {
        warnings.push(format!(
            "{zero} poses on {} have a zero header.stamp: their record time is used",
            topic.name
        ));
    }
    list.sort_by_key(|(t, _, _)| *t);
    let before = list.len();
    list.dedup_by_key(|(t, _, _)| *t);
    if list.len() < before {
        warnings.push(format!(
            "{} poses on {} repeat an earlier time stamp and were dropped",
            before - list.len(),
            topic.name
        ));
    }
    let Some(&(t0, _, _)) = list.first() else {
        return Err(Error::Input(format!(
            "{}: no usable pose on {}{}",
            ob.path().display(),
            topic.name,
            warnings.last().map_or(String::new(), |w| format!(" ({w})"))
        )));
    };
    let epoch = Epoch::at(raw_time(t0));
    // The messages' covariances, when every pose carries a usable one (a pose without would
    // weigh differently from the others: then none is used, and the fit estimates the noise).
    let covs: Vec<Option<Matrix6<f64>>> = list
        .iter()
        .map(|(_, pose, c)| c.as_ref().and_then(|c| ros_pose_covariance(c, pose)))
        .collect();
    let with = covs.iter().filter(|c| c.is_some()).count();
    let carried = list.iter().filter(|(_, _, c)| c.is_some()).count();
    if carried > 0 && with < covs.len() {
        warnings.push(format!(
            "{} of the {} poses on {} carry no usable covariance (not finite, not symmetric or \
             not positive definite, such as ROS's -1 for unknown): the pose noise is estimated \
             from the trajectory fit for all of them",
            covs.len() - with,
            covs.len(),
            topic.name
        ));
    }
    let use_covs = with == covs.len();
    let covariances = use_covs && with > 0;
    let poses = list
        .into_iter()
        .zip(covs)
        .map(|((t, pose, _), cov)| PoseMeasurement {
            t: epoch.rel(raw_time(t)),
            pose,
            cov: if use_covs { cov } else { None },
        })
        .collect();
    let source = if child.is_empty() {
        format!("{} ({})", topic.name, topic.type_name())
    } else {
        format!(
            "{} ({}, child frame {child})",
            topic.name,
            topic.type_name()
        )
    };
    Ok(BagPoses {
        epoch,
        poses,
        source,
        covariances,
        warnings,
    })
}

fn join(v: &[&String]) -> String {
    v.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
}

fn transform_pose(t: &cdr::TransformStamped) -> Decoded {
    let tr = &t.transform;
    (
        t.child_frame_id.trim_start_matches('/').to_string(),
        t.header.stamp,
        cdr::Pose {
            position: cdr::Point {
                x: tr.translation.x,
                y: tr.translation.y,
                z: tr.translation.z,
            },
            orientation: tr.rotation,
        },
        None,
    )
}

/// Largest departure of a pose's quaternion norm from 1 that is taken for rounding (a TUM
/// file's limit).
const QUATERNION_NORM_TOL: f64 = 1e-3;

/// One pose message as decoded: child frame, stamp, pose and covariance (ROS order).
type Decoded = (String, cdr::Time, cdr::Pose, Option<[f64; 36]>);
/// One pose of a child frame: time (ns), pose and covariance (ROS order).
type Stamped = (i64, Se3, Option<[f64; 36]>);

/// The covariance of a ROS pose message (`PoseWithCovariance.covariance`: row-major 6 x 6 over
/// x, y, z and the rotations about the fixed x, y, z axes, all in the parent frame) as the
/// covariance of the right perturbation `[rho; phi]` of `T_parent_child` in the child frame
/// (docs/conventions.md). To first order `T exp([rho; phi]) = (R exp(phi), p + R rho)`, so a
/// position error `dp` and a rotation `dtheta` about the parent's axes are `rho = R^T dp`, `phi =
/// R^T dtheta`: `C = A C_ros A^T`, `A = diag(R^T, R^T)`. `None` when the matrix is no usable
/// covariance: a value not finite, not symmetric, or not positive definite (ROS's -1 for an
/// unknown part, or all zeros).
pub fn ros_pose_covariance(c: &[f64; 36], pose: &Se3) -> Option<Matrix6<f64>> {
    let m = Matrix6::from_row_slice(c);
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let max = m.amax();
    if max <= 0.0 || (m - m.transpose()).amax() > 1e-9 * max {
        return None;
    }
    let ev = m.symmetric_eigenvalues();
    let least = ev.min();
    if least.is_nan() || least <= 1e-12 * max {
        return None;
    }
    let rt = pose.rot.transpose();
    let mut a = Matrix6::zeros();
    a.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
    a.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);
    let out = a * m * a.transpose();
    Some((out + out.transpose()) * 0.5)
}

fn se3_of(p: &cdr::Pose) -> Option<Se3> {
    let q = [
        p.orientation.x,
        p.orientation.y,
        p.orientation.z,
        p.orientation.w,
    ];
    let t = [p.position.x, p.position.y, p.position.z];
    if q.iter().chain(&t).any(|v| !v.is_finite()) {
        return None;
    }
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOL {
        return None;
    }
    let qn = [q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm];
    Some(Se3::from_quaternion_xyzw(
        &qn,
        nalgebra::Vector3::new(t[0], t[1], t[2]),
    ))
}
