//! Reading a flight log into columns, tolerating a file cut off by a crash.

use std::collections::BTreeMap;
use std::path::Path;

use mcap::read::{LinearReader, Options, RawMessageStream};
use mcap::records::Record;
use prost::Message;

use super::schema::{Cycle, Truth};
use super::{LogError, CYCLE_TOPIC, FORMAT, METADATA_NAME, TRUTH_TOPIC};
use crate::control::logged::{LoggedController, LoggedControllerError};
use crate::record::{Columns, CycleRecord, TruthColumns, TruthRecord};

/// A whole log.
#[derive(Clone, Debug, Default)]
pub struct FlightLog {
    pub metadata: BTreeMap<String, String>,
    /// (name, media type, content).
    pub attachments: Vec<(String, String, Vec<u8>)>,
    pub joint_names: Vec<String>,
    pub cycles: Columns,
    pub truth: Option<TruthColumns>,
    /// Messages on JSON channels (the daemon's `/arash/timing` and `/arash/event`): topic →
    /// (log time in ns since the start, document).
    pub json: BTreeMap<String, Vec<(u64, String)>>,
    /// The file ended without its footer (a crash or a run still being written); everything up
    /// to the last complete chunk was read.
    pub truncated: bool,
}

impl FlightLog {
    pub fn dof(&self) -> usize {
        self.joint_names.len()
    }

    pub fn len(&self) -> usize {
        self.cycles.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cycles.t.is_empty()
    }

    /// The controller the log's run was made with, for IDIM-IV: the daemon attaches it to each
    /// run's log as `controller.json`, `arash simulate` names it in `run.json`. `None` when the
    /// log names none; an error when it names one that cannot be read.
    pub fn logged_controller(&self) -> Option<Result<LoggedController, LoggedControllerError>> {
        if let Some(text) = self.attachment_text("controller.json") {
            return Some(LoggedController::from_json(&text));
        }
        Some(LoggedController::from_run_json(&self.attachment_text("run.json")?))
    }

    /// The attachment called `name`, as text.
    pub fn attachment_text(&self, name: &str) -> Option<String> {
        self.attachments.iter().find(|a| a.0 == name).map(|a| String::from_utf8_lossy(&a.2).into_owned())
    }
}

/// Read `path`. A file cut off mid-chunk reads up to its last complete chunk and is marked
/// [`FlightLog::truncated`].
pub fn read_log(path: &Path) -> Result<FlightLog, LogError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| LogError::Io { path: name.clone(), source })?;
    let mut log = FlightLog::default();
    read_records(&bytes, &name, &mut log)?;
    if log.metadata.get("format").map(String::as_str) != Some(FORMAT) {
        return Err(LogError::NotFlightLog {
            path: name,
            problem: format!("no `{METADATA_NAME}` metadata with format {FORMAT}"),
        });
    }
    log.joint_names = log.metadata["joint_names"].split(',').filter(|s| !s.is_empty()).map(str::to_string).collect();
    read_messages(&bytes, &name, &mut log)?;
    check_shapes(&log, &name)?;
    Ok(log)
}

/// Metadata and attachments, which the writer puts before the first cycle.
fn read_records(bytes: &[u8], name: &str, log: &mut FlightLog) -> Result<(), LogError> {
    let reader = LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into())
        .map_err(|source| LogError::NotMcap { path: name.into(), source })?;
    let mut complete = false;
    for record in reader {
        match record {
            Ok(Record::Metadata(m)) if m.name == METADATA_NAME => log.metadata = m.metadata,
            Ok(Record::Attachment { header, data, .. }) => {
                log.attachments.push((header.name, header.media_type, data.into_owned()))
            }
            Ok(Record::Footer(_)) => complete = true,
            Ok(_) => {}
            Err(_) => break,
        }
    }
    log.truncated = !complete;
    Ok(())
}

fn read_messages(bytes: &[u8], name: &str, log: &mut FlightLog) -> Result<(), LogError> {
    let stream = RawMessageStream::new_with_options(bytes, Options::IgnoreEndMagic.into())
        .map_err(|source| LogError::NotMcap { path: name.into(), source })?;
    let mut stream = stream;
    let mut truth = TruthColumns::default();
    let (mut cycle_channel, mut truth_channel) = (None, None);
    let mut cycle = Cycle::default();
    let mut truth_msg = Truth::default();
    let mut record = CycleRecord::new(0);
    let mut truth_record = TruthRecord::new(0);
    while let Some(item) = stream.next() {
        let Ok(message) = item else {
            // Cut off: keep what came before. zstd decodes a cut chunk up to the cut, so the
            // messages of a partly written chunk that arrived whole are kept too.
            log.truncated = true;
            break;
        };
        let id = message.header.channel_id;
        if cycle_channel.is_none() || truth_channel.is_none() {
            match stream.get_channel(id).map(|c| c.topic.clone()).as_deref() {
                Some(CYCLE_TOPIC) => cycle_channel = Some(id),
                Some(TRUTH_TOPIC) => truth_channel = Some(id),
                _ => {}
            }
        }
        let decode_error = |topic: &str, index: usize, source| LogError::Decode {
            path: name.into(),
            topic: topic.into(),
            index,
            source,
        };
        let not_a_record = |topic: &str, index: usize, problem| LogError::NotFlightLog {
            path: name.into(),
            problem: format!("message {index} on {topic}: {problem}"),
        };
        if Some(id) == cycle_channel {
            cycle.clear();
            cycle.merge(&*message.data).map_err(|e| decode_error(CYCLE_TOPIC, log.cycles.t.len(), e))?;
            cycle.to_record(&mut record).map_err(|p| not_a_record(CYCLE_TOPIC, log.cycles.t.len(), p))?;
            log.cycles.push(&record);
        } else if let Some(channel) = stream.get_channel(id).filter(|c| c.message_encoding == "json") {
            let start = log.metadata.get("start_unix_ns").and_then(|s| s.parse::<u64>().ok()).unwrap_or(0);
            log.json.entry(channel.topic.clone()).or_default().push((
                message.header.log_time.saturating_sub(start),
                String::from_utf8_lossy(&message.data).into_owned(),
            ));
        } else if Some(id) == truth_channel {
            truth_msg.clear();
            truth_msg.merge(&*message.data).map_err(|e| decode_error(TRUTH_TOPIC, truth.t.len(), e))?;
            truth_msg.to_record(&mut truth_record).map_err(|p| not_a_record(TRUTH_TOPIC, truth.t.len(), p))?;
            truth.push(&truth_record);
        }
    }
    if truth_channel.is_some() {
        log.truth = Some(truth);
    }
    Ok(())
}

/// Every joint vector must have dof entries per cycle, and each optional vector its width in
/// every cycle or in none.
fn check_shapes(log: &FlightLog, name: &str) -> Result<(), LogError> {
    let (n, dof) = (log.cycles.t.len(), log.dof());
    let c = &log.cycles;
    for (field, v) in c.joint_vectors() {
        if v.len() != n * dof {
            return Err(LogError::NotFlightLog {
                path: name.into(),
                problem: format!("field {field} holds {} values for {n} cycles of {dof} joints", v.len()),
            });
        }
    }
    for (field, v, width) in c.optional_vectors(dof) {
        if !v.is_empty() && v.len() != n * width {
            return Err(LogError::NotFlightLog {
                path: name.into(),
                problem: format!("{field} is present in some cycles only"),
            });
        }
    }
    Ok(())
}
