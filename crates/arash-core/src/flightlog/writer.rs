//! Streaming MCAP writer for control cycles.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Metadata};
use mcap::{Attachment, Compression, WriteOptions, Writer};
use prost::Message;

use super::schema::{descriptor_set, Cycle, Truth, CYCLE_SCHEMA, TRUTH_SCHEMA};
use super::{LogError, CYCLE_TOPIC, FORMAT, METADATA_NAME, TRUTH_TOPIC};
use crate::record::{CycleRecord, TruthRecord};

/// What a log says about its run, written before the first cycle.
#[derive(Clone, Debug, Default)]
pub struct LogHeader {
    /// The robot description (attached as `robot.urdf`).
    pub urdf: String,
    pub joint_names: Vec<String>,
    /// Extra `arash` metadata (scenario, seed, controller, …); `format`, `software_version` and
    /// `joint_names` are added.
    pub metadata: BTreeMap<String, String>,
    /// (name, media type, content) of further attachments, e.g. the run configuration.
    pub attachments: Vec<(String, String, Vec<u8>)>,
    /// Add the `/arash/truth` channel (simulator only).
    pub with_truth: bool,
    /// Unix time of the start of the run (ns); message log times are this plus `t`. Zero gives
    /// log times relative to the start, which keeps simulated logs reproducible.
    pub start_unix_ns: u64,
}

/// Writes one run. Cycles are encoded into reused buffers; a chunk is closed and flushed every
/// `flush_every` cycles (default: one second of log at the cycle rate given to `create`).
pub struct LogWriter {
    path: PathBuf,
    writer: Writer<BufWriter<File>>,
    cycle_channel: u16,
    truth_channel: Option<u16>,
    start_ns: u64,
    flush_every: u64,
    written: u64,
    buffer: Vec<u8>,
    cycle: Cycle,
    truth: Truth,
    /// Channels other than the cycle's and the truth's, by topic, added on first use: schemaless
    /// JSON (timing statistics, events) and the daemon's tracking error.
    channels: BTreeMap<String, u16>,
}

/// How arash writes MCAP: zstd chunks, compressed on the writing thread. mcap's default hands
/// compression to one libzstd worker per physical core. Those threads are made by C with the
/// default 8 MB stacks, and they keep about 40 MB of job buffers. Under the daemon's `mlockall`
/// all of it stays resident, which was 60 of the idle daemon's 100 MB (docs/daemon.md, memory).
/// A 1 kHz log is about 0.6 MB/s before compression. One thread compresses that at a few per
/// cent of a core.
pub(crate) fn write_options(library: String) -> WriteOptions {
    WriteOptions::new().compression(Some(Compression::Zstd)).compression_threads(0).profile("").library(library)
}

impl LogWriter {
    /// Create `path` (replacing it) and write the header, attachments and metadata.
    pub fn create(path: &Path, header: &LogHeader, rate_hz: f64) -> Result<Self, LogError> {
        let io = |source| LogError::Io { path: path.display().to_string(), source };
        let mcap_error = |source| LogError::Mcap { path: path.display().to_string(), source };
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io)?;
        }
        let file = File::create(path).map_err(io)?;
        let options = write_options(format!("arash {}", env!("CARGO_PKG_VERSION"))).chunk_size(None);
        let mut writer = options.create(BufWriter::new(file)).map_err(mcap_error)?;
        let schema = writer.add_schema(CYCLE_SCHEMA, "protobuf", &descriptor_set(CYCLE_SCHEMA)).map_err(mcap_error)?;
        let cycle_channel =
            writer.add_channel(schema, CYCLE_TOPIC, "protobuf", &BTreeMap::new()).map_err(mcap_error)?;
        let truth_channel = if header.with_truth {
            let schema =
                writer.add_schema(TRUTH_SCHEMA, "protobuf", &descriptor_set(TRUTH_SCHEMA)).map_err(mcap_error)?;
            Some(writer.add_channel(schema, TRUTH_TOPIC, "protobuf", &BTreeMap::new()).map_err(mcap_error)?)
        } else {
            None
        };
        // Schemas and channels in a closed chunk of their own: a truncated file still has them.
        writer.flush().map_err(mcap_error)?;
        let mut metadata = header.metadata.clone();
        metadata.insert("format".into(), FORMAT.into());
        metadata.insert("software_version".into(), env!("CARGO_PKG_VERSION").into());
        metadata.insert("joint_names".into(), header.joint_names.join(","));
        metadata.insert("start_unix_ns".into(), header.start_unix_ns.to_string());
        writer.write_metadata(&Metadata { name: METADATA_NAME.into(), metadata }).map_err(mcap_error)?;
        let mut attachments =
            vec![("robot.urdf".to_string(), "application/xml".to_string(), header.urdf.as_bytes().to_vec())];
        attachments.extend(header.attachments.iter().cloned());
        for (name, media_type, data) in attachments {
            let attachment = Attachment {
                log_time: header.start_unix_ns,
                create_time: header.start_unix_ns,
                name,
                media_type,
                data: data.into(),
            };
            writer.attach(&attachment).map_err(mcap_error)?;
        }
        writer.flush().map_err(mcap_error)?;
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            cycle_channel,
            truth_channel,
            start_ns: header.start_unix_ns,
            flush_every: rate_hz.round().max(1.0) as u64,
            written: 0,
            buffer: Vec::with_capacity(1024),
            cycle: Cycle::default(),
            truth: Truth::default(),
            channels: BTreeMap::new(),
        })
    }

    fn mcap_error(&self, source: mcap::McapError) -> LogError {
        LogError::Mcap { path: self.path.display().to_string(), source }
    }

    /// The log time (ns) of file time `t` (s): what every message at `t` is stamped with.
    pub fn log_time(&self, t: f64) -> u64 {
        self.start_ns + (t * 1e9).round() as u64
    }

    /// Append one cycle; returns its `arash.Cycle` encoding, for a caller that sends the same
    /// message elsewhere (the daemon's live stream). After the first cycle this allocates nothing
    /// but what zstd needs.
    pub fn write_cycle(&mut self, r: &CycleRecord) -> Result<&[u8], LogError> {
        self.cycle.fill(r);
        self.buffer.clear();
        self.cycle.encode(&mut self.buffer).expect("a Vec grows as needed");
        let header = MessageHeader {
            channel_id: self.cycle_channel,
            sequence: r.cycle as u32,
            log_time: self.log_time(r.t),
            publish_time: self.log_time(r.t),
        };
        self.writer.write_to_known_channel(&header, &self.buffer).map_err(|e| self.mcap_error(e))?;
        self.written += 1;
        if self.written.is_multiple_of(self.flush_every) {
            self.flush()?;
        }
        Ok(&self.buffer)
    }

    /// Append the ground truth of a cycle (only for logs created `with_truth`).
    pub fn write_truth(&mut self, r: &TruthRecord) -> Result<(), LogError> {
        let channel_id = self.truth_channel.expect("the log was created without the truth channel");
        self.truth.fill(r);
        self.buffer.clear();
        self.truth.encode(&mut self.buffer).expect("a Vec grows as needed");
        let time = self.log_time(r.t);
        let header = MessageHeader { channel_id, sequence: r.cycle as u32, log_time: time, publish_time: time };
        self.writer.write_to_known_channel(&header, &self.buffer).map_err(|e| self.mcap_error(e))
    }

    /// Append a JSON document on `topic` (schemaless, `json` encoding) at run time `t`: the
    /// daemon's timing statistics and events.
    pub fn write_json(&mut self, topic: &str, t: f64, json: &str) -> Result<(), LogError> {
        self.write_message(topic, None, t, json.as_bytes())
    }

    /// Append a protobuf message `data` of schema `schema` (one of [`super::schema`]'s names) on
    /// `topic` at run time `t`.
    pub fn write_protobuf(&mut self, topic: &str, schema: &'static str, t: f64, data: &[u8]) -> Result<(), LogError> {
        self.write_message(topic, Some(schema), t, data)
    }

    fn write_message(
        &mut self,
        topic: &str,
        schema: Option<&'static str>,
        t: f64,
        data: &[u8],
    ) -> Result<(), LogError> {
        let channel_id = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let id = self.add_channel(topic, schema).map_err(|e| self.mcap_error(e))?;
                self.channels.insert(topic.to_string(), id);
                id
            }
        };
        let time = self.log_time(t.max(0.0));
        let header = MessageHeader { channel_id, sequence: 0, log_time: time, publish_time: time };
        self.writer.write_to_known_channel(&header, data).map_err(|e| self.mcap_error(e))
    }

    fn add_channel(&mut self, topic: &str, schema: Option<&'static str>) -> Result<u16, mcap::McapError> {
        match schema {
            None => self.writer.add_channel(0, topic, "json", &BTreeMap::new()),
            Some(name) => {
                let id = self.writer.add_schema(name, "protobuf", &descriptor_set(name))?;
                self.writer.add_channel(id, topic, "protobuf", &BTreeMap::new())
            }
        }
    }

    /// A metadata record named `name`, written now (e.g. what held when the log closed).
    pub fn write_metadata(&mut self, name: &str, metadata: BTreeMap<String, String>) -> Result<(), LogError> {
        let record = Metadata { name: name.into(), metadata };
        self.writer.write_metadata(&record).map_err(|e| self.mcap_error(e))
    }

    /// Close the current chunk and push it to the file.
    pub fn flush(&mut self) -> Result<(), LogError> {
        self.writer.flush().map_err(|e| self.mcap_error(e))
    }

    /// Write the summary and footer. A log that is never finished still reads up to its last
    /// flush.
    pub fn finish(mut self) -> Result<(), LogError> {
        self.writer.finish().map_err(|e| self.mcap_error(e))?;
        Ok(())
    }
}
