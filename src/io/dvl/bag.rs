//! ROS1 bags recorded from the vendor's driver (waterlinked/dvl-a50-ros-driver):
//! `/dvl/json_data` (std_msgs/String, the raw JSON line) and `/dvl/data`
//! (`waterlinked_a50_ros_driver/DVL`, header stamp = host receive time). The bag container is
//! read by [`crate::io::bag::ros1`], damage included; the two message types are decoded here.

use std::collections::BTreeMap;
use std::path::Path;

use super::json;
use super::log::{DvlLogStats, DvlReadOptions};
use super::report::{Parsed, Reject, VelocityReport, content_hash};
use crate::error::{Error, Result};
use crate::io::bag::ros1::Ros1Bag;
use crate::time::RawTime;

/// The topic of the raw JSON strings.
pub const JSON_TOPIC: &str = "/dvl/json_data";
/// The message type of the driver's decoded reports.
pub const DVL_MSG_TYPE: &str = "waterlinked_a50_ros_driver/DVL";

/// How the messages of a topic are decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    JsonString,
    DvlMsg,
}

fn kind_of(tp: &str) -> Option<Kind> {
    if tp == "std_msgs/String" {
        Some(Kind::JsonString)
    } else if tp == DVL_MSG_TYPE || tp.ends_with("/DVL") {
        Some(Kind::DvlMsg)
    } else {
        None
    }
}

/// Callback receiving each decoded message (stats, 1-based message number, result).
pub type Sink<'a> =
    dyn FnMut(&mut DvlLogStats, usize, std::result::Result<Parsed, Reject>) -> Result<()> + 'a;

/// Reads the DVL topic of a ROS1 bag, handing every message to `sink`.
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
            "{}: the ROS bag is damaged (the bag reader failed)",
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
    let bag = Ros1Bag::open(path)?;
    let damage = |stats: &mut DvlLogStats, problems: &[String]| -> Result<()> {
        if opts.strict && !problems.is_empty() {
            return Err(Error::Input(format!(
                "{}: damaged ROS bag: {}",
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
    let conns: BTreeMap<u32, (String, String)> = bag
        .connections()
        .map(|c| (c.id, (c.topic.clone(), c.msg_type.clone())))
        .collect();
    let topic = match &opts.topic {
        Some(t) => t.clone(),
        None => {
            let json_topic = conns
                .values()
                .find(|(t, tp)| t == JSON_TOPIC && tp == "std_msgs/String");
            let dvl_topic = conns.values().find(|(_, tp)| tp == DVL_MSG_TYPE);
            match json_topic.or(dvl_topic) {
                Some((t, _)) => t.clone(),
                None => {
                    return Err(Error::Input(format!(
                        "{}: no DVL topic in this bag (topics: {}); choose one with --dvl-topic",
                        path.display(),
                        topic_list(&conns)
                    )));
                }
            }
        }
    };
    let mut ids: BTreeMap<u32, Kind> = BTreeMap::new();
    let mut type_name = String::new();
    for (id, (t, tp)) in &conns {
        if *t == topic {
            let kind = kind_of(tp).ok_or_else(|| {
                Error::Input(format!(
                    "{}: topic {topic} has type {tp}; expected std_msgs/String (raw JSON) or {DVL_MSG_TYPE}",
                    path.display()
                ))
            })?;
            ids.insert(*id, kind);
            type_name = tp.clone();
        }
    }
    if ids.is_empty() {
        return Err(Error::Input(format!(
            "{}: no topic {topic} in this bag (topics: {})",
            path.display(),
            topic_list(&conns)
        )));
    }
    stats.topic = Some(format!("{topic} ({type_name})"));
    let summary = bag.messages(&|id| ids.contains_key(&id), &mut |msg| {
        let Some(kind) = ids.get(&msg.conn_id) else {
            return Ok(());
        };
        let record_time = RawTime {
            sec: msg.sec as i64,
            frac: msg.nsec.min(999_999_999) as f64 * 1e-9,
        };
        let parsed = match kind {
            Kind::JsonString => decode_string(msg.data).and_then(|s| {
                let mut p = json::parse_line(s)?;
                relabel(&mut p, &topic);
                if let Parsed::Velocity(r) = &mut p {
                    r.host_time = Some(record_time);
                    r.host_time_kind = Some("host receive time (bag record time)");
                }
                Ok(p)
            }),
            Kind::DvlMsg => decode_dvl(msg.data, &topic),
        };
        sink(stats, msg.number, parsed)
    })?;
    damage(stats, &summary.problems)?;
    if let Some(n) = summary.lost_messages.filter(|&n| n > 0) {
        damage(
            stats,
            &[format!(
                "{n} messages of {topic} that the bag's index lists could not be read"
            )],
        )?;
    }
    Ok(())
}

fn topic_list(conns: &BTreeMap<u32, (String, String)>) -> String {
    let mut v: Vec<String> = conns
        .values()
        .map(|(t, tp)| format!("{t} [{tp}]"))
        .collect();
    v.dedup();
    if v.is_empty() {
        "none".to_string()
    } else {
        v.join(", ")
    }
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
