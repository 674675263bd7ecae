//! The IMU's samples from a bag's `sensor_msgs/Imu` topic (ROS 1 `sensor_msgs/Imu`, ROS 2
//! `sensor_msgs/msg/Imu`, in any storage [`Bag`] reads), as [`ImuSample`]s.
//!
//! Read: `header.stamp`, `angular_velocity` (the gyro, rad/s) and `linear_acceleration` (the
//! accelerometer's specific force, m/s^2), both in the IMU's frame as the message gives them.
//! The orientation and the three covariances are decoded (a message must hold them to be a
//! whole `Imu`) but not used: an IMU's orientation is its own filter's estimate, and the
//! covariances drivers fill in are placeholders more often than measurements (the noise comes
//! from the IMU's Kalibr noise figures instead).
//!
//! Times are chosen as for every other topic ([`message_time`]): the header stamp (a zero stamp
//! falls back to the record time, counted), or the record time throughout with
//! `BagTime::Record`. They are kept exact: integer nanoseconds until they are written relative
//! to the whole second of the first sample ([`ImuBagSummary::epoch`]).
//!
//! Nothing read is trusted, and nothing bad is fatal while a sample is left: a message that
//! does not decode, or whose gyro or accelerometer holds a value that is not finite (NaN), is
//! skipped and counted; time going backwards on the topic is counted and the samples are
//! sorted by time; a sample repeating an earlier time stamp is dropped and counted. The first
//! few of each are named by the bag, the topic and the message's 1-based number on the topic.

use std::path::PathBuf;

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::io::bag::Bag;
use crate::io::bag::cdr;
use crate::io::bag::open::{LISTED, message_time};
use crate::io::bag::roles::{BagOptions, BagTime, choose_imu, topic_list};
use crate::io::images::raw_time;
use crate::time::Epoch;
use crate::types::imu::ImuSample;

/// What reading an IMU topic found, beside the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuBagSummary {
    /// The bag read.
    pub bag: PathBuf,
    /// The IMU topic read.
    pub topic: String,
    /// The topic with its type (`/imu/data (sensor_msgs/Imu)`), for summaries.
    pub source: String,
    /// The time the samples are placed at (header stamps or record times).
    pub time: BagTime,
    /// The epoch the samples' times count from: the whole second of the first sample.
    pub epoch: Epoch,
    /// Messages read on the topic.
    pub messages: u64,
    /// Samples returned.
    pub samples: usize,
    /// Messages that did not decode as a `sensor_msgs/Imu` (skipped).
    pub undecodable: usize,
    /// Messages whose angular velocity or linear acceleration holds a value that is not finite
    /// (skipped).
    pub non_finite: usize,
    /// Samples whose time is before the previous sample's, in the bag's order (kept, sorted).
    pub backwards: usize,
    /// Samples repeating an earlier sample's time stamp (dropped; the first one is kept).
    pub repeated: usize,
    /// Messages with a zero `header.stamp`, placed at their record time.
    pub zero_stamps: usize,
    /// Samples per second over the samples' span (`None` for fewer than two samples).
    pub rate_hz: Option<f64>,
    /// The messages named, at most [`LISTED`] of each kind above: `BAG: message N of TOPIC:
    /// what`.
    pub problems: Vec<String>,
    /// What the user should know, one line each: the counts above, the bag's damage.
    pub warnings: Vec<String>,
}

/// One sample as read: the message's number on the topic, its time (ns) and values.
struct Read {
    index: u64,
    t_ns: i64,
    gyro: Vector3<f64>,
    accel: Vector3<f64>,
}

/// The IMU samples of `bag`'s `sensor_msgs/Imu` topic: `options.imu_topic`, or the only Imu
/// topic of the bag (two or more, none named, are an error listing them and asking for
/// `--imu-topic`). Times follow `options.time`. The samples are in time order, their times
/// strictly increasing, relative to the summary's epoch.
///
/// An error when the bag has no Imu topic, when the topic named is missing or of another type,
/// or when not one message of the topic gives a sample (naming the first reason).
pub fn read_imu_from_bag(
    bag: &Bag,
    options: &BagOptions,
) -> Result<(Vec<ImuSample>, ImuBagSummary)> {
    let path = bag.path().to_path_buf();
    let shown = path.display().to_string();
    let topics = bag.topics();
    let idx = choose_imu(topics, options.imu_topic.as_deref())
        .map_err(|e| Error::Input(format!("{shown}: {e}")))?
        .ok_or_else(|| {
            Error::Input(format!(
                "{shown}: no sensor_msgs/Imu topic in this bag (topics: {})",
                topic_list(topics)
            ))
        })?;
    let topic = topics[idx].clone();
    let ser = topic.serialization;
    let name = |index: u64| format!("{shown}: message {index} of {}", topic.name);
    let time = options.time;

    let mut read: Vec<Read> = Vec::new();
    let mut s = ImuBagSummary {
        bag: path.clone(),
        topic: topic.name.clone(),
        source: format!("{} ({})", topic.name, topic.type_name()),
        time,
        epoch: Epoch::default(),
        messages: 0,
        samples: 0,
        undecodable: 0,
        non_finite: 0,
        backwards: 0,
        repeated: 0,
        zero_stamps: 0,
        rate_hz: None,
        problems: Vec::new(),
        warnings: bag
            .problems()
            .iter()
            .map(|p| format!("{shown}: {p}"))
            .collect(),
    };
    let (mut undecodable, mut non_finite) = (Vec::new(), Vec::new());
    // The decompressors are third-party code working on untrusted bytes: a panic inside them
    // becomes an error naming the bag rather than taking the program down.
    let pass = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        bag.messages(&|i| i == idx, &mut |m| {
            s.messages += 1;
            match cdr::decode::<cdr::Imu>(m.data, ser) {
                Err(e) => count(&mut s.undecodable, &mut undecodable, || {
                    format!("{}: {e}", name(m.index))
                }),
                Ok(imu) => {
                    let w = &imu.angular_velocity;
                    let a = &imu.linear_acceleration;
                    let gyro = Vector3::new(w.x, w.y, w.z);
                    let accel = Vector3::new(a.x, a.y, a.z);
                    if gyro.iter().chain(accel.iter()).all(|v| v.is_finite()) {
                        let stamp = imu.header.stamp.as_nanos();
                        read.push(Read {
                            index: m.index,
                            t_ns: message_time(stamp, m.log_time_ns, time, &mut s.zero_stamps),
                            gyro,
                            accel,
                        });
                    } else {
                        count(&mut s.non_finite, &mut non_finite, || {
                            format!(
                                "{}: a value that is not finite: angular_velocity {:?}, \
                                 linear_acceleration {:?}",
                                name(m.index),
                                [w.x, w.y, w.z],
                                [a.x, a.y, a.z]
                            )
                        });
                    }
                }
            }
            Ok(())
        })
    }));
    let summary = match pass {
        Ok(r) => r?,
        Err(_) => {
            return Err(Error::Input(format!(
                "{shown}: the bag is damaged (the bag reader failed while reading {})",
                topic.name
            )));
        }
    };
    s.warnings
        .extend(summary.problems.iter().map(|p| format!("{shown}: {p}")));

    let (kept, backwards, repeated) = time_order(read, &mut s, &name);
    push_warnings(&mut s, [&undecodable, &non_finite, &backwards, &repeated]);
    s.problems = [undecodable, non_finite, backwards, repeated].concat();

    let (Some(first), Some(last)) = (kept.first(), kept.last()) else {
        return Err(Error::Input(format!(
            "{shown}: no usable IMU sample on {} ({} messages{})",
            topic.name,
            s.messages,
            s.problems.first().map_or(String::new(), |p| {
                let p = p.strip_prefix(&format!("{shown}: ")).unwrap_or(p);
                format!("; first problem: {p}")
            })
        )));
    };
    s.epoch = Epoch::at(raw_time(first.t_ns));
    let span_s = (last.t_ns - first.t_ns) as f64 * 1e-9;
    s.rate_hz = (kept.len() >= 2 && span_s > 0.0).then(|| (kept.len() - 1) as f64 / span_s);
    s.samples = kept.len();
    let samples = kept
        .iter()
        .map(|r| ImuSample {
            t: s.epoch.rel(raw_time(r.t_ns)),
            gyro: r.gyro,
            accel: r.accel,
        })
        .collect();
    Ok((samples, s))
}

/// Counts one problem in `n`, and names its message in `named` while fewer than [`LISTED`] are.
fn count(n: &mut usize, named: &mut Vec<String>, what: impl FnOnce() -> String) {
    *n += 1;
    if named.len() < LISTED {
        named.push(what());
    }
}

/// The samples in time order, as the bag holds them: each step back counted and named, the
/// samples sorted (stably: of two samples with one time stamp the earlier message is kept),
/// then each repeated time stamp counted, named and dropped. Returns the samples kept and the
/// messages named going back and repeating.
fn time_order(
    mut read: Vec<Read>,
    s: &mut ImuBagSummary,
    name: &dyn Fn(u64) -> String,
) -> (Vec<Read>, Vec<String>, Vec<String>) {
    let (mut backwards, mut repeated) = (Vec::new(), Vec::new());
    for w in read.windows(2) {
        if w[1].t_ns < w[0].t_ns {
            count(&mut s.backwards, &mut backwards, || {
                format!(
                    "{}: time goes back {:.9} s from message {}",
                    name(w[1].index),
                    (w[0].t_ns - w[1].t_ns) as f64 * 1e-9,
                    w[0].index
                )
            });
        }
    }
    read.sort_by_key(|r| r.t_ns);
    let mut kept: Vec<Read> = Vec::with_capacity(read.len());
    for r in read {
        match kept.last() {
            Some(last) if last.t_ns == r.t_ns => {
                count(&mut s.repeated, &mut repeated, || {
                    format!(
                        "{}: repeats the time stamp of message {} (dropped)",
                        name(r.index),
                        last.index
                    )
                });
            }
            _ => kept.push(r),
        }
    }
    (kept, backwards, repeated)
}

/// The summary's counts as warnings, each naming the bag, the topic and the first message
/// (`named`: the messages named of each count, in the order undecodable, not finite, backwards,
/// repeated).
fn push_warnings(s: &mut ImuBagSummary, named: [&[String]; 4]) {
    let prefix = format!("{}: ", s.bag.display());
    let first = |k: usize| {
        named[k].first().map_or(String::new(), |p| {
            format!(" (first: {})", p.strip_prefix(&prefix).unwrap_or(p))
        })
    };
    let n = |count: usize, noun: &str| match count {
        1 => format!("1 {noun}"),
        _ => format!("{count} {noun}s"),
    };
    // Each count with its noun and what happened to those messages ({} is the count).
    let rows = [
        (
            s.undecodable,
            "message",
            "{} skipped, not decodable as sensor_msgs/Imu",
            Some(0),
        ),
        (
            s.non_finite,
            "message",
            "{} skipped, an angular velocity or linear acceleration not finite (NaN)",
            Some(1),
        ),
        (
            s.backwards,
            "time",
            "time goes backwards {}; the samples were sorted by time",
            Some(2),
        ),
        (
            s.repeated,
            "sample",
            "{} dropped, repeating an earlier time stamp",
            Some(3),
        ),
        (
            s.zero_stamps,
            "message",
            "{} with a zero header.stamp, placed at the record time",
            None,
        ),
    ];
    let out: Vec<String> = rows
        .into_iter()
        .filter(|(count, ..)| *count > 0)
        .map(|(count, noun, what, k)| {
            let what = what.replace("{}", &n(count, noun));
            let first = k.map_or(String::new(), first);
            format!("{prefix}{}: {what}{first}", s.topic)
        })
        .collect();
    s.warnings.extend(out);
}
