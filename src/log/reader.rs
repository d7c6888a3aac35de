//! Reads a run log record by record, keeping everything readable from a damaged file: a truncated
//! tail or a chunk that fails to decompress is counted as lost, not fatal.

use super::{RunIdentity, RESULT_METADATA, RUN_METADATA};
use crate::sim::RunResult;
use crate::{Error, Result};
use mcap::records::Record;
use std::collections::BTreeMap;
use std::path::Path;

/// One decoded message.
#[derive(Clone, Debug)]
pub struct LoggedMessage {
    pub topic: String,
    pub log_time_ns: u64,
    pub sequence: u32,
    pub data: Vec<u8>,
}

/// Everything readable from a log, and what was lost.
#[derive(Debug, Default)]
pub struct LogContents {
    pub identity: Option<RunIdentity>,
    pub result: Option<RunResult>,
    pub messages: Vec<LoggedMessage>,
    pub chunks_read: u64,
    /// Chunks that failed to decompress, plus a chunk cut off by truncation.
    pub chunks_lost: u64,
    /// Known from the summary statistics, or from gaps in the sequence numbers when the summary is
    /// missing (messages of a cut-off tail cannot be counted then: see `complete`).
    pub messages_lost: u64,
    /// The file ended with a valid summary section and footer.
    pub complete: bool,
    /// The first read problem, if any (one line).
    pub problem: Option<String>,
}

impl LogContents {
    /// Messages per topic, in topic-name order.
    pub fn counts(&self) -> BTreeMap<String, u64> {
        let mut c = BTreeMap::new();
        for m in &self.messages {
            *c.entry(m.topic.clone()).or_default() += 1;
        }
        c
    }

    /// Whether anything was lost or the file was not properly finished.
    pub fn is_damaged(&self) -> bool {
        !self.complete || self.chunks_lost > 0 || self.messages_lost > 0
    }

    /// Messages of `topic`, in log order.
    pub fn topic<'a>(&'a self, topic: &'a str) -> impl Iterator<Item = &'a LoggedMessage> + 'a {
        self.messages.iter().filter(move |m| m.topic == topic)
    }
}

/// Reads `path`; only a file that is not an MCAP file at all (or cannot be read) is an error.
pub fn read_log(path: &Path) -> Result<LogContents> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_log_bytes(&bytes).map_err(|msg| Error::Runtime(format!("{}: {msg}", path.display())))
}

/// [`read_log`] on bytes in memory.
pub fn read_log_bytes(bytes: &[u8]) -> std::result::Result<LogContents, String> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err("not an MCAP file (no MCAP magic at the start)".into());
    }
    let options = mcap::read::Options::IgnoreEndMagic.into();
    let reader = mcap::read::LinearReader::new_with_options(bytes, options)
        .map_err(|e| format!("not an MCAP file ({e})"))?;
    let mut out = LogContents::default();
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut expected_messages = None;
    let mut expected_chunks = None;
    let mut chunk_indexes = 0u64;
    for record in reader {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                // A truncated file ends mid-record: usually inside a chunk.
                out.chunks_lost += 1;
                out.problem
                    .get_or_insert(format!("file ends mid-record ({e})"));
                break;
            }
        };
        match record {
            Record::Channel(c) => {
                topics.insert(c.id, c.topic);
            }
            Record::Chunk { header, data } => {
                let inner = mcap::read::ChunkReader::new(header, &data);
                let mut ok = true;
                let mut batch = Vec::new();
                match inner {
                    Ok(inner) => {
                        for r in inner {
                            match r {
                                Ok(Record::Channel(c)) => {
                                    topics.insert(c.id, c.topic);
                                }
                                Ok(Record::Message { header, data }) => {
                                    batch.push((header, data.into_owned()))
                                }
                                Ok(_) => {}
                                Err(e) => {
                                    ok = false;
                                    out.problem.get_or_insert(format!("damaged chunk ({e})"));
                                    break;
                                }
                            }
                        }
                    }
                    Err(e) => {
                        ok = false;
                        out.problem.get_or_insert(format!("damaged chunk ({e})"));
                    }
                }
                if ok {
                    out.chunks_read += 1;
                    for (h, data) in batch {
                        out.messages.push(LoggedMessage {
                            topic: topics.get(&h.channel_id).cloned().unwrap_or_default(),
                            log_time_ns: h.log_time,
                            sequence: h.sequence,
                            data,
                        });
                    }
                } else {
                    out.chunks_lost += 1;
                }
            }
            Record::Message { header, data } => out.messages.push(LoggedMessage {
                topic: topics.get(&header.channel_id).cloned().unwrap_or_default(),
                log_time_ns: header.log_time,
                sequence: header.sequence,
                data: data.into_owned(),
            }),
            Record::Metadata(m) if m.name == RUN_METADATA => {
                out.identity = RunIdentity::from_map(&m.metadata);
            }
            Record::Metadata(m) if m.name == RESULT_METADATA => {
                out.result = m
                    .metadata
                    .get("result")
                    .and_then(|j| serde_json::from_str(j).ok());
            }
            Record::Statistics(s) => {
                expected_messages = Some(s.message_count);
                expected_chunks = Some(u64::from(s.chunk_count));
            }
            Record::ChunkIndex(_) => chunk_indexes += 1,
            Record::Footer(_) => out.complete = true,
            _ => {}
        }
    }
    let _ = chunk_indexes;
    out.messages.sort_by_key(|m| (m.log_time_ns, m.sequence));
    let decoded = out.messages.len() as u64;
    match (expected_messages, expected_chunks) {
        (Some(m), Some(c)) => {
            out.messages_lost = m.saturating_sub(decoded);
            out.chunks_lost = c.saturating_sub(out.chunks_read).max(out.chunks_lost);
        }
        _ => {
            // No summary: sequence numbers are consecutive from 0 across all topics, so the gaps
            // below the highest one read are lost messages.
            let max_seq = out.messages.iter().map(|m| u64::from(m.sequence)).max();
            out.messages_lost = max_seq.map_or(0, |s| s + 1 - decoded);
        }
    }
    if out.messages_lost > 0 && out.problem.is_none() {
        out.problem = Some(format!("{} messages missing", out.messages_lost));
    }
    Ok(out)
}
