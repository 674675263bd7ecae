//! DVL reports from a bag: ROS 1 bags recorded from the vendor's ROS 1 driver
//! (waterlinked/dvl-a50-ros-driver: `/dvl/json_data`, std_msgs/String, the raw JSON line, and
//! `/dvl/data`, `waterlinked_a50_ros_driver/DVL`, header stamp = host receive time), and ROS 2
//! bags (MCAP or sqlite3) from Water Linked's ROS 2 driver (`marine_acoustic_msgs/Dvl`,
//! header stamp = time of validity, validity from `beam_velocities_valid`, covariance from
//! `velocity_covar`; or its `nav_msgs/Odometry`), or any
//! `geometry_msgs/TwistWithCovarianceStamped`. The container is read by [`crate::io::bag`],
//! the topic chosen by [`crate::io::bag::roles::choose_dvl`]; the messages are decoded here.
//!
//! Times: the JSON strings carry the DVL's own; the typed ROS 2 messages carry their header
//! stamp as the time of validity (a zero stamp is replaced by the record time, counted and
//! warned about); every message also carries its record time as the host receive time
//! (`--dvl-time host`).

use std::path::Path;

use super::json;
use super::log::{DvlLogStats, DvlReadOptions};
use super::report::{Parsed, Reject, VelocityReport, content_hash};
use crate::error::{Error, Result};
use crate::io::bag::cdr::{self, CdrMessage};
use crate::io::bag::roles::{Kind, choose_dvl, kind, topic_list};
use crate::io::bag::{Bag, Serialization, Topic};
use crate::time::RawTime;

/// Callback receiving each decoded message (stats, 1-based message number, result).
pub type Sink<'a> =
    dyn FnMut(&mut DvlLogStats, usize, std::result::Result<Parsed, Reject>) -> Result<()> + 'a;

/// Reads the DVL topic of a bag (ROS 1, or ROS 2 in either storage), handing every message to
/// `sink`.
pub fn read_bag(
    path: &Path,
    opts: &DvlReadOptions,
    stats: &mut DvlLogStats,
    sink: &mut Sink<'_>,
) -> Result<()> {
    // The decompressors are third-party code working on untrusted bytes: a panic inside them
    // becomes an error naming the file rather than taking the program down.
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        read_bag_inner(path, opts, stats, sink)
    })) {
        Ok(r) => r,
        Err(_) => Err(Error::Input(format!(
            "{}: the bag is damaged (the bag reader failed)",
            path.display()
        ))),
    }
}

fn read_bag_inner(
    path: &Path,
    opts: &DvlReadOptions,
    stats: &mut DvlLogStats,
    sink: &mut Sink<'_>,
) -> Result<()> {
    let bag = Bag::open(path)?;
    let damage = |stats: &mut DvlLogStats, problems: &[String]| -> Result<()> {
        if opts.strict && !problems.is_empty() {
            return Err(Error::Input(format!(
                "{}: damaged bag: {}",
                path.display(),
                problems.join("; ")
            )));
        }
        stats
            .warnings
            .extend(problems.iter().map(|p| format!("bag: {p}")));
        Ok(())
    };
    damage(stats, bag.problems())?;
    stats
        .warnings
        .extend(bag.notes().iter().map(|n| format!("bag: {n}")));
    let topics = bag.topics();
    let Some(idx) = choose_dvl(topics, opts.topic.as_deref())? else {
        return Err(Error::Input(format!(
            "{}: no DVL topic in this bag (topics: {}); choose one with --dvl-topic",
            path.display(),
            topic_list(topics)
        )));
    };
    let topic = topics[idx].clone();
    let Some(k) = kind(&topic) else {
        return Err(Error::Input(format!(
            "{}: topic {} has type {}, which is not a DVL report",
            path.display(),
            topic.name,
            topic.msg_type
        )));
    };
    stats.topic = Some(format!("{} ({})", topic.name, topic.msg_type));
    stats.bag_topic = Some(topic.name.clone());
    let mut zero_stamps = 0usize;
    let summary = bag.messages(&|i| i == idx, &mut |msg| {
        let record_time = RawTime::from_nanos(msg.log_time_ns);
        let parsed = decode(k, &topic, msg.data, record_time, &mut zero_stamps);
        sink(stats, msg.index as usize, parsed)
    })?;
    damage(stats, &summary.problems)?;
    if zero_stamps > 0 {
        stats.warnings.push(format!(
            "{zero_stamps} messages of {} have a zero header.stamp: their record time is used",
            topic.name
        ));
    }
    Ok(())
}

/// Decodes one DVL message of kind `k`.
fn decode(
    k: Kind,
    topic: &Topic,
    data: &[u8],
    record_time: RawTime,
    zero_stamps: &mut usize,
) -> std::result::Result<Parsed, Reject> {
    let ser = topic.serialization;
    let name = &topic.name;
    match k {
        Kind::String => {
            let text: std::borrow::Cow<'_, [u8]> = match ser {
                Serialization::Ros1 => decode_string(data)?.into(),
                Serialization::Cdr => decode_typed::<cdr::StringMsg>(data, ser)?
                    .data
                    .into_bytes()
                    .into(),
            };
            let mut p = json::parse_line(&text)?;
            relabel(&mut p, name);
            if let Parsed::Velocity(r) = &mut p {
                r.host_time = Some(record_time);
                r.host_time_kind = Some("host receive time (bag record time)");
            }
            Ok(p)
        }
        Kind::A50Dvl if ser == Serialization::Ros1 => decode_dvl(data, name),
        Kind::MarineDvl => {
            let m: cdr::Dvl = decode_typed(data, ser)?;
            let cov = finite_cov(&m.velocity_covar);
            typed_report(
                "marine_acoustic_msgs/Dvl",
                name,
                data,
                [m.velocity.x, m.velocity.y, m.velocity.z],
                cov,
                m.beam_velocities_valid,
                &m.header.stamp,
                record_time,
                zero_stamps,
            )
        }
        Kind::Odometry | Kind::TwistCov => {
            let (label, stamp, twist) = if k == Kind::Odometry {
                let m: cdr::Odometry = decode_typed(data, ser)?;
                ("nav_msgs/Odometry", m.header.stamp, m.twist)
            } else {
                let m: cdr::TwistWithCovarianceStamped = decode_typed(data, ser)?;
                (
                    "geometry_msgs/TwistWithCovarianceStamped",
                    m.header.stamp,
                    m.twist,
                )
            };
            let l = twist.twist.linear;
            typed_report(
                label,
                name,
                data,
                [l.x, l.y, l.z],
                linear_block(&twist.covariance),
                true,
                &stamp,
                record_time,
                zero_stamps,
            )
        }
        _ => Err(Reject::new(
            "not a DVL message",
            format!("{} messages are not DVL reports", topic.msg_type),
        )),
    }
}

/// Decodes a typed message, turning a decoding error into a rejected message.
fn decode_typed<M: CdrMessage>(data: &[u8], ser: Serialization) -> std::result::Result<M, Reject> {
    cdr::decode::<M>(data, ser).map_err(|e| Reject::new("malformed message", e.to_string()))
}

/// The velocity block of a 6x6 row-major twist covariance; `None` when it says nothing (all
/// zeros, ROS's -1 for "unknown", or a value that is not finite).
fn linear_block(c: &[f64; 36]) -> Option<[f64; 9]> {
    let mut out = [0.0; 9];
    for r in 0..3 {
        for k in 0..3 {
            out[r * 3 + k] = c[r * 6 + k];
        }
    }
    finite_cov(&out)
}

/// A 3x3 covariance, unless it says nothing (all zeros, a negative variance) or is not finite.
fn finite_cov(c: &[f64; 9]) -> Option<[f64; 9]> {
    let usable = c.iter().all(|v| v.is_finite())
        && c.iter().any(|&v| v != 0.0)
        && [c[0], c[4], c[8]].iter().all(|&v| v >= 0.0);
    usable.then_some(*c)
}

/// A velocity report from a typed ROS message: the header stamp is the time of validity (the
/// record time when the stamp is zero), the record time the host receive time.
#[allow(clippy::too_many_arguments)]
fn typed_report(
    type_label: &str,
    topic: &str,
    data: &[u8],
    v: [f64; 3],
    cov: Option<[f64; 9]>,
    valid: bool,
    stamp: &cdr::Time,
    record_time: RawTime,
    zero_stamps: &mut usize,
) -> std::result::Result<Parsed, Reject> {
    if v.iter().any(|x| !x.is_finite()) {
        if !valid {
            // An invalid report may carry NaN: it is counted as invalid, not malformed.
            return Ok(Parsed::Velocity(VelocityReport {
                label: format!("{type_label} (bag {topic})"),
                v: [0.0; 3],
                cov: None,
                valid: false,
                time_ms: None,
                time_of_validity_us: None,
                time_of_transmission_us: None,
                host_time: Some(record_time),
                host_time_kind: Some("host receive time (bag record time)"),
                key: content_hash(data),
            }));
        }
        return Err(Reject::new(
            "non-finite value",
            format!("velocity {v:?} in a report marked valid"),
        ));
    }
    let stamp_ns = stamp.as_nanos();
    let tov_us = if stamp_ns == 0 {
        *zero_stamps += 1;
        record_time.sec * 1_000_000 + (record_time.frac * 1e6).round() as i64
    } else {
        stamp_ns.div_euclid(1000)
    };
    Ok(Parsed::Velocity(VelocityReport {
        label: format!("{type_label} (bag {topic})"),
        v,
        cov,
        valid,
        time_ms: None,
        time_of_validity_us: Some(tov_us),
        time_of_transmission_us: None,
        host_time: Some(record_time),
        host_time_kind: Some("host receive time (bag record time)"),
        key: content_hash(data),
    }))
}

fn relabel(p: &mut Parsed, topic: &str) {
    let label = match p {
        Parsed::Velocity(r) => &mut r.label,
        Parsed::WaterVelocity { label }
        | Parsed::Config { label, .. }
        | Parsed::Other { label, .. } => label,
    };
    *label = format!("{label} (rosbag {topic})");
}

/// A little-endian reader over a serialised ROS message.
struct Reader<'a> {
    b: &'a [u8],
    i: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> std::result::Result<&'a [u8], Reject> {
        let end = self
            .i
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or_else(|| Reject::new("truncated message", "message shorter than its type"))?;
        let s = &self.b[self.i..end];
        self.i = end;
        Ok(s)
    }
    fn u32(&mut self) -> std::result::Result<u32, Reject> {
        let s = self.take(4)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn u64(&mut self) -> std::result::Result<u64, Reject> {
        let s = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(s);
        Ok(u64::from_le_bytes(a))
    }
    fn f64(&mut self, name: &str) -> std::result::Result<f64, Reject> {
        let v = f64::from_bits(self.u64()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(Reject::new("non-finite value", format!("{name} is {v}")))
        }
    }
    fn bool(&mut self) -> std::result::Result<bool, Reject> {
        Ok(self.take(1)?[0] != 0)
    }
    fn string(&mut self) -> std::result::Result<&'a [u8], Reject> {
        let n = self.u32()? as usize;
        self.take(n)
    }
}

/// The bytes of a serialised std_msgs/String.
fn decode_string(data: &[u8]) -> std::result::Result<&[u8], Reject> {
    let mut r = Reader { b: data, i: 0 };
    let s = r.string()?;
    if r.i != data.len() {
        return Err(Reject::new(
            "truncated message",
            "std_msgs/String with trailing bytes",
        ));
    }
    Ok(s)
}

/// Decodes a `waterlinked_a50_ros_driver/DVL`: Header, time, velocity (Vector3), fom, altitude,
/// DVLBeam[] (id int64, velocity, distance, rssi, nsd float64, valid bool), velocity_valid,
/// status int64, form string. It carries no covariance and no DVL-clock time stamp; its header
/// stamp is the host receive time.
fn decode_dvl(data: &[u8], topic: &str) -> std::result::Result<Parsed, Reject> {
    let mut r = Reader { b: data, i: 0 };
    let _seq = r.u32()?;
    let sec = r.u32()?;
    let nsec = r.u32()?;
    let _frame = r.string()?;
    let identity_start = r.i;
    let time = r.f64("time")?;
    let v = [r.f64("vx")?, r.f64("vy")?, r.f64("vz")?];
    let _fom = r.f64("fom")?;
    let _alt = r.f64("altitude")?;
    let beams = r.u32()? as usize;
    if beams > 64 {
        return Err(Reject::new("truncated message", format!("{beams} beams")));
    }
    for _ in 0..beams {
        r.take(8)?;
        for name in ["beam velocity", "beam distance", "beam rssi", "beam nsd"] {
            r.f64(name)?;
        }
        r.bool()?;
    }
    let valid = r.bool()?;
    let _status = r.u64()?;
    let form = r.string()?;
    if r.i != data.len() {
        return Err(Reject::new(
            "truncated message",
            "DVL message with trailing bytes",
        ));
    }
    let form: String = String::from_utf8_lossy(form).chars().take(32).collect();
    Ok(Parsed::Velocity(VelocityReport {
        label: format!("{form} (rosbag {topic})"),
        v,
        cov: None,
        valid,
        time_ms: Some(time),
        time_of_validity_us: None,
        time_of_transmission_us: None,
        host_time: Some(RawTime {
            sec: sec as i64,
            frac: nsec.min(999_999_999) as f64 * 1e-9,
        }),
        host_time_kind: Some("host receive time (DVL message header stamp)"),
        key: content_hash(&data[identity_start..]),
    }))
}
