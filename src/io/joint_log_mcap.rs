//! ROS 2 bags in MCAP (`treecal pair --joints BAG.mcap`): the `sensor_msgs/msg/JointState`
//! messages of one topic, read with Foxglove's `mcap` crate (its only user). Records are
//! streamed, each limited to [`MAX_MCAP_RECORD_BYTES`], and chunk checksums are checked.

use super::joint_log::JointLog;
use super::ros_joint_state::decode_joint_state;
use super::units::{AngleUnit, LengthUnit};
use crate::error::{Error, Result};
use crate::limits::{check_count, MAX_CSV_ROWS};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufReader, Read};
use std::path::Path;

/// The schema name of the messages read.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";

/// Largest MCAP record (a chunk or a message), bytes: rosbag2 writes chunks of about 1 MB.
pub const MAX_MCAP_RECORD_BYTES: usize = 256 << 20;

/// The 8 bytes every MCAP file starts with.
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Whether the file starts with the MCAP magic bytes.
pub fn is_mcap(path: &Path) -> Result<bool> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let mut head = Vec::with_capacity(8);
    std::fs::File::open(path)
        .map_err(io)?
        .take(8)
        .read_to_end(&mut head)
        .map_err(io)?;
    Ok(head == MAGIC)
}

/// Reads the JointState messages of `topic` (or of the only topic that has them). Times are
/// the header stamps, or the log times when every stamp is zero; positions are in rad and m.
pub fn read_joint_log_mcap(path: &Path, topic: Option<&str>) -> Result<JointLog> {
    let origin = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_record_length_limit(MAX_MCAP_RECORD_BYTES)
        .with_validate_chunk_crcs(true);
    let reader = mcap::io::MessageReader::new_with_options(BufReader::new(file), options);
    let fail = |place: String, message: String| Error::InvalidData {
        origin: place,
        message,
    };
    let mut topics: BTreeMap<String, usize> = BTreeMap::new();
    let mut messages = Vec::new();
    for (index, message) in reader.enumerate() {
        let message = message.map_err(|e| {
            fail(
                format!("{origin}: record after message {index}"),
                format!("not a readable MCAP file: {e}"),
            )
        })?;
        let channel = &message.channel;
        let is_joint_state = channel
            .schema
            .as_ref()
            .is_some_and(|s| s.name == JOINT_STATE_SCHEMA);
        if !is_joint_state {
            continue;
        }
        *topics.entry(channel.topic.clone()).or_default() += 1;
        if topic.is_some_and(|t| t != channel.topic) {
            continue;
        }
        if channel.message_encoding != "cdr" {
            return Err(fail(
                format!("{origin}: topic {}", channel.topic),
                format!(
                    "message encoding '{}'; only cdr (ROS 2) is read",
                    channel.message_encoding
                ),
            ));
        }
        check_count(
            messages.len() + 1,
            MAX_CSV_ROWS,
            &origin,
            "joint-state messages",
        )?;
        let place = format!(
            "{origin}: message {} ({} log time {} ns)",
            index + 1,
            channel.topic,
            message.log_time
        );
        let decoded = decode_joint_state(&message.data)
            .map_err(|e| fail(place.clone(), format!("not a JointState message: {e}")))?;
        messages.push((channel.topic.clone(), message.log_time, decoded, place));
    }
    let chosen = choose_topic(&origin, topic, &topics)?;
    let use_log_time = messages.iter().all(|m| m.2.stamp == 0.0);
    let mut log = JointLog {
        origin: origin.clone(),
        names: Vec::new(),
        times: Vec::new(),
        values: Vec::new(),
        places: Vec::new(),
        angle_unit: AngleUnit::Radian,
        joint_length_unit: LengthUnit::Metre,
    };
    let mut columns: HashMap<String, usize> = HashMap::new();
    // (time, (column, value) per joint given, place) per message.
    type Sample = (f64, Vec<(usize, f64)>, String);
    let mut ordered: Vec<Sample> = Vec::new();
    for (topic, log_time, message, place) in messages {
        if topic != chosen {
            continue;
        }
        let time = if use_log_time {
            log_time as f64 * 1e-9
        } else {
            message.stamp
        };
        let mut values = Vec::with_capacity(message.names.len());
        for (name, value) in message.names.into_iter().zip(message.positions) {
            let next = columns.len();
            let column = *columns.entry(name.clone()).or_insert(next);
            if column == log.names.len() {
                log.names.push(name);
            }
            values.push((column, value));
        }
        ordered.push((time, values, place));
    }
    // Header stamps of several publishers need not arrive in order.
    ordered.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (time, values, place) in ordered {
        log.push_time(time, &place)?;
        let mut row = vec![f64::NAN; log.names.len()];
        for (column, value) in values {
            row[column] = value;
        }
        log.values.push(row);
        log.places.push(place);
    }
    Ok(log)
}

/// The topic to read: the one asked for, or the only one with JointState messages.
fn choose_topic(
    origin: &str,
    topic: Option<&str>,
    topics: &BTreeMap<String, usize>,
) -> Result<String> {
    let listed = || {
        topics
            .iter()
            .map(|(t, n)| format!("{t} ({n} messages)"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let fail = |message: String| Error::InvalidData {
        origin: origin.to_owned(),
        message,
    };
    match (topic, topics.len()) {
        (_, 0) => Err(fail(format!(
            "no {JOINT_STATE_SCHEMA} messages (with a schema of that name) in the bag"
        ))),
        (Some(t), _) if topics.contains_key(t) => Ok(t.to_owned()),
        (Some(t), _) => Err(fail(format!(
            "no {JOINT_STATE_SCHEMA} messages on topic '{t}'; topics with them: {}",
            listed()
        ))),
        (None, 1) => Ok(topics.keys().next().cloned().unwrap_or_default()),
        (None, _) => Err(fail(format!(
            "{JOINT_STATE_SCHEMA} messages on several topics: {}; choose one with `joint_topic`",
            listed()
        ))),
    }
}
