//! ROS 2 bags (MCAP and sqlite3 storage) and ROS 1 bags through `dvlcal::io::bag::Bag`,
//! against fixtures that independent tools wrote (`scripts/make_bag_fixtures.py`: rosbags and
//! foxglove's mcap writer). `tests/fixtures/bags/expected.json` lists every message in record
//! order with its bytes, so each reader is checked byte for byte; then the fixtures are cut,
//! corrupted and replaced by random bytes, and the readers must give what is left, say what
//! was lost, and never panic.

mod tmp_common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dvlcal::io::bag::cdr::{CdrMessage, Dvl, Image, PoseStamped, StringMsg};
use dvlcal::io::bag::{Bag, MCAP_MAGIC, Serialization, Storage};
use proptest::prelude::*;
use tmp_common::TmpDir;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bags")
}

/// One expected message.
#[derive(Clone, PartialEq, Eq)]
struct Msg {
    topic: String,
    log_time_ns: i64,
    data: Vec<u8>,
}

impl std::fmt::Debug for Msg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let sum = self
            .data
            .iter()
            .fold(0u32, |a, &b| a.wrapping_mul(31).wrapping_add(b.into()));
        write!(
            f,
            "{} at {} ({} bytes, sum {sum:08x})",
            self.topic,
            self.log_time_ns,
            self.data.len()
        )
    }
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

/// The messages of `expected.json` in one serialisation ("cdr" or "ros1"), with their types.
fn expected(ser: &str) -> (Vec<Msg>, BTreeMap<String, (String, u64)>) {
    let text = std::fs::read_to_string(fixtures().join("expected.json")).expect("expected.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let mut types = BTreeMap::new();
    let msgs = v[ser]
        .as_array()
        .expect("a list")
        .iter()
        .map(|m| {
            let topic = m["topic"].as_str().expect("topic").to_string();
            let e = types
                .entry(topic.clone())
                .or_insert((m["type"].as_str().expect("type").to_string(), 0));
            e.1 += 1;
            Msg {
                topic,
                log_time_ns: m["log_time_ns"].as_i64().expect("time"),
                data: hex(m["data"].as_str().expect("data")),
            }
        })
        .collect();
    (msgs, types)
}

/// Every message of every topic, with the per-topic indexes checked on the way.
fn read_all(bag: &Bag) -> (Vec<Msg>, Vec<String>) {
    read_some(bag, &|_| true)
}

fn read_some(bag: &Bag, wanted: &dyn Fn(usize) -> bool) -> (Vec<Msg>, Vec<String>) {
    let mut out = Vec::new();
    let mut seen = vec![0u64; bag.topics().len()];
    let summary = bag
        .messages(wanted, &mut |m| {
            assert!(wanted(m.topic), "topic {} was not asked for", m.topic);
            seen[m.topic] += 1;
            assert_eq!(m.index, seen[m.topic], "per-topic index");
            out.push(Msg {
                topic: bag.topics()[m.topic].name.clone(),
                log_time_ns: m.log_time_ns,
                data: m.data.to_vec(),
            });
            Ok(())
        })
        .unwrap_or_else(|e| panic!("{}: {e}", bag.path().display()));
    assert_eq!(summary.messages as usize, out.len());
    (out, summary.problems)
}

const MCAP: [&str; 5] = [
    "mcap_zstd",
    "none.mcap",
    "lz4.mcap",
    "unchunked.mcap",
    "split_mcap",
];
const SQLITE: [&str; 3] = ["sqlite", "bare.db3", "split_sqlite"];
const ROS1: [&str; 3] = ["ros1_none.bag", "ros1_bz2.bag", "ros1_lz4.bag"];

fn open(name: &str) -> Bag {
    Bag::open(&fixtures().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn check_topics(
    name: &str,
    bag: &Bag,
    ser: Serialization,
    types: &BTreeMap<String, (String, u64)>,
) {
    let got: BTreeMap<String, (String, Option<u64>)> = bag
        .topics()
        .iter()
        .map(|t| {
            assert_eq!(t.serialization, ser, "{name}: {}", t.name);
            (t.name.clone(), (t.type_name(), t.declared_count))
        })
        .collect();
    assert_eq!(
        got.len(),
        bag.topics().len(),
        "{name}: a topic listed twice"
    );
    let want: BTreeMap<String, (String, Option<u64>)> = types
        .iter()
        .map(|(k, (tp, n))| {
            let declared = if ser == Serialization::Ros1 {
                None
            } else {
                Some(*n)
            };
            (k.clone(), (dvlcal::io::bag::normalize_type(tp), declared))
        })
        .collect();
    assert_eq!(got, want, "{name}");
}

#[test]
fn every_fixture_opens_with_its_storage_topics_and_counts() {
    let (_, types) = expected("cdr");
    for name in MCAP {
        let bag = open(name);
        assert_eq!(bag.storage(), Storage::Mcap, "{name}");
        assert!(bag.problems().is_empty(), "{name}: {:?}", bag.problems());
        check_topics(name, &bag, Serialization::Cdr, &types);
        // ROS 2 spells the types with /msg/.
        assert!(bag.topics().iter().all(|t| t.msg_type.contains("/msg/")));
    }
    for name in SQLITE {
        let bag = open(name);
        assert_eq!(bag.storage(), Storage::Sqlite3, "{name}");
        assert!(bag.problems().is_empty(), "{name}: {:?}", bag.problems());
        check_topics(name, &bag, Serialization::Cdr, &types);
    }
    let (_, types1) = expected("ros1");
    for name in ROS1 {
        let bag = open(name);
        assert_eq!(bag.storage(), Storage::Ros1, "{name}");
        check_topics(name, &bag, Serialization::Ros1, &types1);
    }
}

#[test]
fn every_fixture_streams_its_messages_in_record_order_byte_for_byte() {
    let (cdr, _) = expected("cdr");
    for name in MCAP.iter().chain(SQLITE.iter()) {
        let (got, problems) = read_all(&open(name));
        assert!(problems.is_empty(), "{name}: {problems:?}");
        assert_eq!(got.len(), cdr.len(), "{name}");
        for (i, (g, e)) in got.iter().zip(&cdr).enumerate() {
            assert_eq!(g, e, "{name}: message {i}");
        }
    }
    let (ros1, _) = expected("ros1");
    for name in ROS1 {
        let (got, problems) = read_all(&open(name));
        assert!(problems.is_empty(), "{name}: {problems:?}");
        assert_eq!(got, ros1, "{name}");
    }
}

#[test]
fn the_messages_decode_to_the_values_written() {
    let bag = open("mcap_zstd");
    let topic = |n: &str| {
        bag.topics()
            .iter()
            .position(|t| t.name == n)
            .expect("topic")
    };
    let (chatter, pose, image, dvl) = (
        topic("/chatter"),
        topic("/pose"),
        topic("/cam0/image_raw"),
        topic("/dvl/velocity_report"),
    );
    let t0 = 1_700_000_000_000_000_000i64;
    let mut n = [0usize; 4];
    bag.messages(&|_| true, &mut |m| {
        let k = (m.log_time_ns - t0) / 50_000_000;
        if m.topic == chatter {
            assert_eq!(StringMsg::decode(m.data)?.data, format!("hello {k}"));
            n[0] += 1;
        } else if m.topic == pose {
            let p = PoseStamped::decode(m.data)?;
            assert_eq!(p.header.frame_id, "map");
            assert_eq!(p.pose.position.x, 0.5 * k as f64);
            // The stamp is 20 ms before the record time.
            let stamp = p.header.stamp.sec * 1_000_000_000 + i64::from(p.header.stamp.nanosec);
            assert_eq!(stamp, m.log_time_ns - 20_000_000);
            n[1] += 1;
        } else if m.topic == image {
            let i = Image::decode(m.data)?;
            assert_eq!((i.width, i.height, i.encoding.as_str()), (8, 4, "mono8"));
            assert_eq!(i.data.len(), 32);
            n[2] += 1;
        } else if m.topic == dvl {
            let d = Dvl::decode(m.data)?;
            assert_eq!(d.header.frame_id, "dvl_link");
            assert_eq!(d.beam_velocities_valid, k != 5);
            n[3] += 1;
        }
        Ok(())
    })
    .expect("read");
    assert_eq!(n, [4, 12, 6, 10]);
}

#[test]
fn wanted_selects_topics_and_indexes_count_within_them() {
    let (cdr, _) = expected("cdr");
    for name in MCAP.iter().chain(SQLITE.iter()) {
        let bag = open(name);
        let dvl = bag
            .topics()
            .iter()
            .position(|t| t.name == "/dvl/velocity_report")
            .expect("dvl topic");
        let (got, _) = read_some(&bag, &|t| t == dvl);
        let want: Vec<Msg> = cdr
            .iter()
            .filter(|m| m.topic == "/dvl/velocity_report")
            .cloned()
            .collect();
        assert_eq!(got, want, "{name}");
        let (none, _) = read_some(&bag, &|_| false);
        assert!(none.is_empty(), "{name}");
    }
}

#[test]
fn an_error_from_the_callback_stops_the_pass() {
    for name in MCAP.iter().chain(SQLITE.iter()) {
        let bag = open(name);
        let mut n = 0;
        let r = bag.messages(&|_| true, &mut |_| {
            n += 1;
            if n == 3 {
                Err(dvlcal::Error::Input("enough".into()))
            } else {
                Ok(())
            }
        });
        assert!(r.is_err_and(|e| e.to_string() == "enough"), "{name}");
        assert_eq!(n, 3, "{name}");
    }
}

/// The top-level records of an MCAP file: (offset, opcode, content length).
fn mcap_records(b: &[u8]) -> Vec<(usize, u8, usize)> {
    let mut out = Vec::new();
    let mut p = 8;
    while p + 9 <= b.len() - 8 {
        let op = b[p];
        let len = u64::from_le_bytes(b[p + 1..p + 9].try_into().unwrap()) as usize;
        out.push((p, op, len));
        p += 9 + len;
    }
    out
}

/// Opens `path` and reads all its messages, comparing them with a prefix of `full` (by topic
/// name, time and bytes). Returns how many came and the problems told.
fn read_cut(path: &Path, full: &[Msg]) -> Result<(usize, Vec<String>), String> {
    let bag = Bag::open(path).map_err(|e| e.to_string())?;
    let mut problems = bag.problems().to_vec();
    let mut got = Vec::new();
    let s = bag
        .messages(&|_| true, &mut |m| {
            got.push(Msg {
                topic: bag.topics()[m.topic].name.clone(),
                log_time_ns: m.log_time_ns,
                data: m.data.to_vec(),
            });
            Ok(())
        })
        .map_err(|e| e.to_string())?;
    problems.extend(s.problems);
    assert!(
        got.len() <= full.len() && got[..] == full[..got.len()],
        "{}: the messages are not a prefix of the bag's: {got:?}",
        path.display()
    );
    Ok((got.len(), problems))
}

/// Cuts each file at many points (every byte near its start and end, every 53rd between):
/// opening and reading must give a prefix of its messages and a problem, or an error naming
/// the file.
fn cut_each(tag: &str, files: &[(&str, &[Msg])]) {
    let tmp = TmpDir::new(tag);
    for &(name, full) in files {
        let bytes = std::fs::read(fixtures().join(name)).expect("fixture");
        let ext = Path::new(name).extension().expect("ext").to_string_lossy();
        let path = tmp.0.join(format!("cut.{ext}"));
        let n = bytes.len();
        let cuts: Vec<usize> = (0..n)
            .filter(|&c| c < 200 || c + 200 > n || c % 53 == 0)
            .collect();
        let (mut errors, mut most) = (0, 0);
        for &c in &cuts {
            std::fs::write(&path, &bytes[..c]).expect("write");
            match read_cut(&path, full) {
                Ok((got, problems)) => {
                    most = most.max(got);
                    // Cutting the closing bytes of an MCAP file loses no message, but the
                    // reader still says the file was not closed.
                    assert!(!problems.is_empty(), "{name} cut at {c}: no problem told");
                }
                Err(e) => {
                    errors += 1;
                    assert!(
                        e.contains("cut."),
                        "{name} cut at {c}: {e} does not name the file"
                    );
                }
            }
        }
        if ext == "db3" {
            // SQLite would read a cut database's missing pages as zeros: refused.
            assert_eq!(errors, cuts.len(), "{name}: a cut database was read");
        } else {
            // Most cuts of the record-structured files leave something to read.
            assert!(
                errors < cuts.len() / 2,
                "{name}: {errors} of {} cuts failed",
                cuts.len()
            );
            assert!(
                most + 1 >= full.len(),
                "{name}: at most {most} messages from a cut"
            );
        }
    }
}

#[test]
fn cut_mcap_files_give_the_messages_before_the_cut_and_say_so() {
    let (cdr, _) = expected("cdr");
    cut_each(
        "ros2-bag-cut-mcap",
        &[
            ("mcap_zstd/mcap_zstd.mcap", &cdr),
            ("none.mcap", &cdr),
            ("lz4.mcap", &cdr),
            ("unchunked.mcap", &cdr),
        ],
    );
}

#[test]
fn cut_sqlite_files_are_refused_by_name() {
    let (cdr, _) = expected("cdr");
    cut_each("ros2-bag-cut-db3", &[("bare.db3", &cdr)]);
}

#[test]
fn cut_ros1_bags_give_the_messages_before_the_cut_and_say_so() {
    let (ros1, _) = expected("ros1");
    cut_each(
        "ros2-bag-cut-ros1",
        &[
            ("ros1_none.bag", &ros1),
            ("ros1_bz2.bag", &ros1),
            ("ros1_lz4.bag", &ros1),
        ],
    );
}

#[test]
fn a_corrupted_compressed_chunk_is_skipped_and_counted() {
    let tmp = TmpDir::new("ros2-bag-corrupt");
    let (cdr, _) = expected("cdr");
    for (name, probe) in [("lz4.mcap", 0.5), ("mcap_zstd/mcap_zstd.mcap", 0.0)] {
        let bytes = std::fs::read(fixtures().join(name)).expect("fixture");
        let chunks: Vec<(usize, usize)> = mcap_records(&bytes)
            .into_iter()
            .filter(|r| r.1 == 0x06)
            .map(|r| (r.0, r.2))
            .collect();
        assert!(chunks.len() >= 3, "{name}: {} chunks", chunks.len());
        let (at, len) = chunks[1];
        // The records start after the chunk's fixed fields and its compression name.
        let name_len = u32::from_le_bytes(bytes[at + 9 + 28..at + 9 + 32].try_into().unwrap());
        let records = at + 9 + 32 + name_len as usize + 8;
        let end = at + 9 + len;
        let pos = records + ((end - records) as f64 * probe) as usize;
        let mut bad = bytes.clone();
        bad[pos] ^= 0x5a;
        let path = tmp.0.join("corrupt.mcap");
        std::fs::write(&path, &bad).expect("write");
        let bag = Bag::open(&path).expect("open");
        // The topics come from the summary: opening reads no chunk.
        assert!(bag.problems().is_empty(), "{name}: {:?}", bag.problems());
        let (got, problems) = read_all(&bag);
        let lost = cdr.len() - got.len();
        assert!(lost > 0 && lost < cdr.len() / 2, "{name}: {lost} lost");
        // The others come, in order, the last included.
        let mut it = cdr.iter();
        assert!(
            got.iter().all(|g| it.any(|e| e == g)),
            "{name}: not a subsequence"
        );
        assert_eq!(got.last(), cdr.last(), "{name}");
        assert_eq!(problems.len(), 1, "{name}: {problems:?}");
        let p = &problems[0];
        assert!(
            p.contains(&format!("chunk at byte {at}")) && p.contains(&format!("{lost} messages")),
            "{name}: {p}"
        );
    }
}

/// A hand-made MCAP file: the records given, between the magic and a footer without summary.
fn mcap_file(records: &[(u8, Vec<u8>)], footer: bool) -> Vec<u8> {
    let mut b = MCAP_MAGIC.to_vec();
    let rec = |b: &mut Vec<u8>, op: u8, content: &[u8]| {
        b.push(op);
        b.extend_from_slice(&(content.len() as u64).to_le_bytes());
        b.extend_from_slice(content);
    };
    let mut header = Vec::new();
    for s in ["ros2", "test"] {
        header.extend_from_slice(&(s.len() as u32).to_le_bytes());
        header.extend_from_slice(s.as_bytes());
    }
    rec(&mut b, 0x01, &header);
    for (op, c) in records {
        rec(&mut b, *op, c);
    }
    if footer {
        rec(&mut b, 0x0F, &[0; 4]);
        rec(&mut b, 0x02, &[0; 20]);
        b.extend_from_slice(MCAP_MAGIC);
    }
    b
}

fn s(x: &str) -> Vec<u8> {
    let mut v = (x.len() as u32).to_le_bytes().to_vec();
    v.extend_from_slice(x.as_bytes());
    v
}

fn schema(id: u16, name: &str) -> (u8, Vec<u8>) {
    let mut c = id.to_le_bytes().to_vec();
    c.extend(s(name));
    c.extend(s("ros2msg"));
    c.extend(s(""));
    (0x03, c)
}

fn channel(id: u16, schema: u16, topic: &str, encoding: &str) -> (u8, Vec<u8>) {
    let mut c = id.to_le_bytes().to_vec();
    c.extend_from_slice(&schema.to_le_bytes());
    c.extend(s(topic));
    c.extend(s(encoding));
    c.extend_from_slice(&0u32.to_le_bytes());
    (0x04, c)
}

fn message(channel: u16, t: u64, data: &[u8]) -> (u8, Vec<u8>) {
    let mut c = channel.to_le_bytes().to_vec();
    c.extend_from_slice(&0u32.to_le_bytes());
    c.extend_from_slice(&t.to_le_bytes());
    c.extend_from_slice(&t.to_le_bytes());
    c.extend_from_slice(data);
    (0x05, c)
}

fn chunk(compression: &str, records: &[(u8, Vec<u8>)]) -> (u8, Vec<u8>) {
    let mut inner = Vec::new();
    for (op, c) in records {
        inner.push(*op);
        inner.extend_from_slice(&(c.len() as u64).to_le_bytes());
        inner.extend_from_slice(c);
    }
    let mut c = [0u8; 16].to_vec();
    c.extend_from_slice(&(inner.len() as u64).to_le_bytes());
    c.extend_from_slice(&0u32.to_le_bytes());
    c.extend(s(compression));
    c.extend_from_slice(&(inner.len() as u64).to_le_bytes());
    c.extend_from_slice(&inner);
    (0x06, c)
}

#[test]
fn other_encodings_are_listed_but_never_read() {
    let tmp = TmpDir::new("ros2-bag-json");
    let path = tmp.0.join("json.mcap");
    let b = mcap_file(
        &[
            schema(1, "std_msgs/msg/String"),
            channel(1, 1, "/json", "json"),
            channel(2, 1, "/cdr", "cdr"),
            channel(3, 1, "/ros1", "ros1"),
            message(1, 5, b"{\"data\": 1}"),
            message(2, 6, &[0, 1, 0, 0, 1, 0, 0, 0, 0]),
            message(3, 7, &[0, 0, 0, 0]),
        ],
        true,
    );
    std::fs::write(&path, b).expect("write");
    let bag = Bag::open(&path).expect("open");
    let names: Vec<&str> = bag.topics().iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["/json", "/cdr", "/ros1"]);
    assert_eq!(bag.topics()[2].serialization, Serialization::Ros1);
    assert!(
        bag.problems()
            .iter()
            .any(|p| p.contains("/json") && p.contains("\"json\"")),
        "{:?}",
        bag.problems()
    );
    let (got, _) = read_all(&bag);
    let topics: Vec<&str> = got.iter().map(|m| m.topic.as_str()).collect();
    assert_eq!(topics, ["/cdr", "/ros1"]);
}

#[test]
fn unknown_compression_and_bad_chunks_are_described() {
    let tmp = TmpDir::new("ros2-bag-handmade");
    let path = tmp.0.join("chunks.mcap");
    let inner = [
        schema(1, "std_msgs/msg/String"),
        channel(1, 1, "/a", "cdr"),
        message(1, 10, b"one"),
    ];
    let brotli = chunk("brotli", &inner);
    let second = chunk("", &[message(1, 11, b"two")]);
    // A chunk whose one record claims more bytes than the chunk holds: the most significant
    // byte of the record's length (before the 27 bytes of the message).
    let mut third = chunk("", &[message(1, 12, b"three")]);
    let l = third.1.len();
    third.1[l - 27 - 1] = 0xff;
    let b = mcap_file(
        &[
            chunk("", &inner),
            brotli,
            second,
            third,
            message(1, 13, b"four"),
        ],
        false,
    );
    std::fs::write(&path, b).expect("write");
    let bag = Bag::open(&path).expect("open");
    assert_eq!(bag.topics().len(), 1);
    // No footer: read whole for topics, and said.
    assert!(
        bag.problems().iter().any(|p| p.contains("footer")),
        "{:?}",
        bag.problems()
    );
    let (got, problems) = read_all(&bag);
    let data: Vec<&[u8]> = got.iter().map(|m| &m.data[..]).collect();
    assert_eq!(data, [&b"one"[..], b"two", b"four"]);
    assert!(
        problems.iter().any(|p| p.contains("\"brotli\"")),
        "{problems:?}"
    );
    assert!(
        problems.iter().any(|p| p.contains("damaged record")),
        "{problems:?}"
    );
}

#[test]
fn a_database_that_is_not_a_bag_is_refused_by_name() {
    let tmp = TmpDir::new("ros2-bag-notabag");
    let path = tmp.0.join("other.db3");
    {
        let db = rusqlite::Connection::open(&path).expect("create");
        db.execute_batch("CREATE TABLE things(id INTEGER PRIMARY KEY, name TEXT);")
            .expect("table");
    }
    let e = Bag::open(&path).expect_err("not a bag").to_string();
    assert!(
        e.contains("other.db3") && e.contains("not a ROS 2 bag"),
        "{e}"
    );
    // Garbage after the sqlite3 magic.
    let mut b = b"SQLite format 3\0".to_vec();
    b.extend((0..5000u32).map(|i| (i * 7919 % 251) as u8));
    let path = tmp.0.join("garbage.db3");
    std::fs::write(&path, b).expect("write");
    let e = Bag::open(&path).expect_err("garbage").to_string();
    assert!(e.contains("garbage.db3"), "{e}");
}

#[test]
fn a_metadata_yaml_naming_a_missing_file_is_refused() {
    let tmp = TmpDir::new("ros2-bag-missing");
    let dir = tmp.0.join("bag");
    std::fs::create_dir_all(&dir).expect("folder");
    std::fs::copy(
        fixtures().join("split_mcap/metadata.yaml"),
        dir.join("metadata.yaml"),
    )
    .expect("copy");
    std::fs::copy(
        fixtures().join("split_mcap/split_mcap_0.mcap"),
        dir.join("split_mcap_0.mcap"),
    )
    .expect("copy");
    let e = Bag::open(&dir).expect_err("missing file").to_string();
    assert!(
        e.contains("split_mcap_1.mcap") && e.contains("missing"),
        "{e}"
    );
}

#[test]
fn a_split_bag_reads_both_files_in_order() {
    let (cdr, _) = expected("cdr");
    for name in ["split_mcap", "split_sqlite"] {
        let bag = open(name);
        // Each topic once, though both files declare it.
        assert_eq!(bag.topics().len(), 4, "{name}");
        let (got, _) = read_all(&bag);
        assert_eq!(got, cdr, "{name}");
    }
}

fn run_on(path: &Path) {
    if let Ok(bag) = Bag::open(path) {
        let _ = bag.messages(&|_| true, &mut |m| {
            assert!(m.topic < bag.topics().len());
            Ok(())
        });
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_after_the_mcap_magic_never_panic(
        tail in proptest::collection::vec(any::<u8>(), 0..3000),
        with_header in any::<bool>(),
    ) {
        let tmp = TmpDir::new("ros2-bag-random");
        let path = tmp.0.join("random.mcap");
        // Half the time past a valid Header, so the bytes reach the record walk.
        let mut b = if with_header { mcap_file(&[], false) } else { MCAP_MAGIC.to_vec() };
        b.extend_from_slice(&tail);
        std::fs::write(&path, b).expect("write");
        run_on(&path);
    }

    #[test]
    fn random_records_inside_a_chunk_never_panic(
        records in proptest::collection::vec(any::<u8>(), 0..2000),
        declared in prop_oneof![Just(None), (0u64..4000).prop_map(Some)],
        footer in any::<bool>(),
    ) {
        let tmp = TmpDir::new("ros2-bag-random-chunk");
        let path = tmp.0.join("chunk.mcap");
        // An uncompressed chunk whose records are random, declaring their size or another.
        let mut c = [0u8; 16].to_vec();
        c.extend_from_slice(&declared.unwrap_or(records.len() as u64).to_le_bytes());
        c.extend_from_slice(&0u32.to_le_bytes());
        c.extend(s(""));
        c.extend_from_slice(&(records.len() as u64).to_le_bytes());
        c.extend_from_slice(&records);
        let b = mcap_file(
            &[schema(1, "std_msgs/msg/String"), channel(1, 1, "/a", "cdr"), (0x06, c)],
            footer,
        );
        std::fs::write(&path, b).expect("write");
        run_on(&path);
    }

    #[test]
    fn mutated_mcap_fixtures_never_panic(
        which in 0usize..3,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let tmp = TmpDir::new("ros2-bag-mutated");
        let name = ["lz4.mcap", "none.mcap", "mcap_zstd/mcap_zstd.mcap"][which];
        let mut b = std::fs::read(fixtures().join(name)).expect("fixture");
        for (i, v) in edits {
            let n = b.len();
            b[i.index(n)] = v;
        }
        let path = tmp.0.join("mutated.mcap");
        std::fs::write(&path, b).expect("write");
        run_on(&path);
    }

    #[test]
    fn mutated_databases_never_panic(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let tmp = TmpDir::new("ros2-bag-mutated-db3");
        let mut b = std::fs::read(fixtures().join("bare.db3")).expect("fixture");
        for (i, v) in edits {
            let n = b.len();
            b[i.index(n)] = v;
        }
        let path = tmp.0.join("mutated.db3");
        std::fs::write(&path, b).expect("write");
        run_on(&path);
    }
}
