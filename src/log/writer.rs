//! Writes a run log: zstd chunks, the run identity as metadata at the start, the result as
//! metadata at the end, then the summary section (statistics, chunk indexes).

use super::record::Sink;
use super::topics::{Topic, TOPICS};
use super::{RunIdentity, RESULT_METADATA, RUN_METADATA};
use crate::config::LogConfig;
use crate::sim::RunResult;
use crate::{Error, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// An open MCAP run log; the first write error is kept and returned by [`RunLog::close`].
pub struct RunLog {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    /// Messages written per topic.
    pub counts: BTreeMap<&'static str, u64>,
    error: Option<Error>,
}

impl RunLog {
    /// Creates (or, the caller having checked `--force`, replaces) `path` and writes the header,
    /// schemas, channels and the run identity.
    pub fn create(path: &Path, identity: &RunIdentity, cfg: &LogConfig) -> Result<RunLog> {
        let io = |e: mcap::McapError| Error::io(path, std::io::Error::other(e.to_string()));
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(cfg.zstd_level)
            .chunk_size(Some(cfg.chunk_size_kb * 1024))
            .profile("")
            .library(format!("tensorscout {}", crate::VERSION))
            .create(BufWriter::new(file))
            .map_err(io)?;
        let mut channels = BTreeMap::new();
        for t in TOPICS {
            let schema = writer
                .add_schema(t.schema_name, "jsonschema", t.schema_json.as_bytes())
                .map_err(io)?;
            let id = writer
                .add_channel(schema, t.name, "json", &BTreeMap::new())
                .map_err(io)?;
            channels.insert(t.name, id);
        }
        writer
            .write_metadata(&mcap::records::Metadata {
                name: RUN_METADATA.into(),
                metadata: identity.to_map(),
            })
            .map_err(io)?;
        Ok(RunLog {
            path: path.to_path_buf(),
            writer: Some(writer),
            channels,
            sequence: 0,
            counts: BTreeMap::new(),
            error: None,
        })
    }

    fn keep(&mut self, r: std::result::Result<(), mcap::McapError>) {
        if let (Err(e), None) = (r, &self.error) {
            self.error = Some(Error::io(&self.path, std::io::Error::other(e.to_string())));
        }
    }

    /// Writes the summary section and closes the file; returns the first error of the whole log.
    pub fn close(mut self) -> Result<BTreeMap<&'static str, u64>> {
        if let Some(mut w) = self.writer.take() {
            let r = w.finish().map(|_| ());
            self.keep(r);
        }
        match self.error {
            Some(e) => Err(e),
            None => Ok(self.counts),
        }
    }
}

impl Sink for RunLog {
    fn put(&mut self, topic: &'static Topic, time_ns: u64, message: Vec<u8>) {
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        let header = mcap::records::MessageHeader {
            channel_id: self.channels[topic.name],
            sequence: self.sequence,
            log_time: time_ns,
            publish_time: time_ns,
        };
        self.sequence += 1;
        let r = w.write_to_known_channel(&header, &message);
        *self.counts.entry(topic.name).or_default() += 1;
        self.keep(r);
    }

    fn finish(&mut self, result: &RunResult) {
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        let json = serde_json::to_string(result).expect("results serialise");
        let r = w.write_metadata(&mcap::records::Metadata {
            name: RESULT_METADATA.into(),
            metadata: [("result".to_string(), json)].into_iter().collect(),
        });
        self.keep(r);
    }
}
