//! A bag listed as `dvlcal bag-info` prints it: every topic with its type, message count, rate
//! and span, and the part dvlcal would give it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::io::bag::roles::{self, BagOptions, Roles};
use crate::io::bag::{Bag, Topic};
use crate::io::images::raw_time;
use crate::time::Epoch;

/// One topic as `dvlcal bag-info` lists it.
#[derive(Clone, Debug)]
pub struct TopicInfo {
    /// The topic.
    pub topic: Topic,
    /// Messages read.
    pub count: u64,
    /// First and last record time, Unix ns (0 without messages).
    pub first_ns: i64,
    /// Last record time, Unix ns.
    pub last_ns: i64,
    /// The part dvlcal gives it (`images cam0`, `DVL`, ...; `-` for none).
    pub role: String,
}

/// Fewest messages a rate is given for: fewer intervals than this minus one make a rate that is
/// one interval's inverse.
pub const RATE_MIN_MESSAGES: u64 = 5;
/// Shortest span, seconds, a rate is given for: messages recorded within less (a burst, a
/// latched topic, a bag written at once) have no rate to speak of.
pub const RATE_MIN_SPAN_S: f64 = 1.0;

impl TopicInfo {
    /// Seconds from the first message to the last.
    pub fn span_s(&self) -> f64 {
        (self.last_ns - self.first_ns) as f64 * 1e-9
    }

    /// Messages per second over the topic's span, when that says something: at least
    /// [`RATE_MIN_MESSAGES`] messages over at least [`RATE_MIN_SPAN_S`] (`None` otherwise; the
    /// count and the span are what there is).
    pub fn rate_hz(&self) -> Option<f64> {
        let span = self.span_s();
        (self.count >= RATE_MIN_MESSAGES && span >= RATE_MIN_SPAN_S)
            .then(|| (self.count - 1) as f64 / span)
    }
}

/// What `dvlcal bag-info` prints.
#[derive(Clone, Debug)]
pub struct BagInfo {
    /// The bag.
    pub path: PathBuf,
    /// Its storage's name.
    pub storage: &'static str,
    /// One per topic, sorted by name (then type).
    pub topics: Vec<TopicInfo>,
    /// How the parts were chosen, or why they could not be.
    pub notes: Vec<String>,
    /// Damage met.
    pub problems: Vec<String>,
}

/// Reads every message's record time once and lists the topics with their counts, rates and
/// spans, and the part dvlcal would give each under `options`.
pub fn bag_info(path: &Path, options: &BagOptions) -> Result<BagInfo> {
    let bag = Bag::open(path)?;
    let (roles, mut notes) = match roles::assign(bag.topics(), options) {
        Ok(r) => {
            let notes = r.notes.clone();
            (r, notes)
        }
        Err(e) => (Roles::default(), vec![format!("no roles: {e}")]),
    };
    let n = bag.topics().len();
    let mut count = vec![0u64; n];
    let mut first = vec![i64::MAX; n];
    let mut last = vec![i64::MIN; n];
    let summary = bag.messages(&|_| true, &mut |m| {
        if let Some(c) = count.get_mut(m.topic) {
            *c += 1;
            first[m.topic] = first[m.topic].min(m.log_time_ns);
            last[m.topic] = last[m.topic].max(m.log_time_ns);
        }
        Ok(())
    })?;
    let mut topics: Vec<TopicInfo> = bag
        .topics()
        .iter()
        .enumerate()
        .map(|(i, t)| TopicInfo {
            topic: t.clone(),
            count: count[i],
            first_ns: if count[i] > 0 { first[i] } else { 0 },
            last_ns: if count[i] > 0 { last[i] } else { 0 },
            role: roles::role_name(&roles, i),
        })
        .collect();
    // By name, as `rostopic list` and `ros2 bag info` list them, whatever order the bag
    // declared them in.
    topics.sort_by(|a, b| {
        (&a.topic.name, &a.topic.msg_type).cmp(&(&b.topic.name, &b.topic.msg_type))
    });
    let unrated = topics
        .iter()
        .filter(|t| t.count > 0 && t.rate_hz().is_none())
        .count();
    if unrated > 0 {
        notes.push(format!(
            "rate \"-\": {unrated} topic(s) with fewer than {RATE_MIN_MESSAGES} messages or a span \
             under {RATE_MIN_SPAN_S} s, which give no rate worth printing: their count and span \
             are shown"
        ));
    }
    notes.extend(bag.notes().iter().cloned());
    if roles.images.is_empty() && roles.pose.is_none() {
        notes.push("no image or pose topic: nothing gives the camera's motion".into());
    }
    if roles.dvl.is_none() {
        notes.push("no DVL topic".into());
    }
    let mut problems = bag.problems().to_vec();
    problems.extend(summary.problems);
    Ok(BagInfo {
        path: path.to_path_buf(),
        storage: bag.storage().name(),
        topics,
        notes,
        problems,
    })
}

impl BagInfo {
    /// The listing: one line per topic, then the notes and the damage.
    pub fn render(&self) -> String {
        let mut s = format!("{} ({})\n", self.path.display(), self.storage);
        let _ = writeln!(
            s,
            "{:<40} {:<44} {:>8} {:>9} {:>9}  role",
            "topic", "type", "messages", "rate Hz", "span s"
        );
        for t in &self.topics {
            let rate = match t.rate_hz() {
                Some(r) => format!("{r:.2}"),
                None => "-".to_string(),
            };
            let _ = writeln!(
                s,
                "{:<40} {:<44} {:>8} {:>9} {:>9.2}  {}",
                t.topic.name,
                t.topic.type_name(),
                t.count,
                rate,
                t.span_s(),
                t.role
            );
        }
        if let (Some(a), Some(b)) = (
            self.topics
                .iter()
                .filter(|t| t.count > 0)
                .map(|t| t.first_ns)
                .min(),
            self.topics
                .iter()
                .filter(|t| t.count > 0)
                .map(|t| t.last_ns)
                .max(),
        ) {
            let _ = writeln!(
                s,
                "record times {} to {} ({:.2} s)",
                Epoch::at(raw_time(a)).format_abs(raw_frac(a), 3),
                Epoch::at(raw_time(b)).format_abs(raw_frac(b), 3),
                (b - a) as f64 * 1e-9
            );
        }
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        for p in &self.problems {
            let _ = writeln!(s, "damage: {p}");
        }
        s
    }
}

/// The fraction of a second of a nanosecond time, in seconds.
fn raw_frac(t_ns: i64) -> f64 {
    t_ns.rem_euclid(1_000_000_000) as f64 * 1e-9
}
