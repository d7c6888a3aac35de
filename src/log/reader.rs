//! Reads a run log record by record, keeping everything readable from a damaged file: a truncated
//! tail or a chunk that fails to decompress is counted as lost, not fatal.

use super::{RunIdentity, RESULT_METADATA, RUN_METADATA};
use crate::sim::RunResult;
use crate::{Error, Result};
use mcap::records::op;
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
    /// The file ended with a valid summary section and footer, and holds the run's identity and
    /// result metadata.
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

    /// Whether anything was lost or damaged, or the file was not properly finished.
    pub fn is_damaged(&self) -> bool {
        !self.complete || self.chunks_lost > 0 || self.messages_lost > 0 || self.problem.is_some()
    }

    /// Messages of `topic`, in log order.
    pub fn topic<'a>(&'a self, topic: &'a str) -> impl Iterator<Item = &'a LoggedMessage> + 'a {
        self.messages.iter().filter(move |m| m.topic == topic)
    }
}

/// Largest log file read (far above a 1,800 s run's few MB).
pub const MAX_LOG_BYTES: u64 = 4 << 30;

/// Reads `path`; only a file that is not an MCAP file at all (or cannot be read) is an error.
pub fn read_log(path: &Path) -> Result<LogContents> {
    let bytes = crate::util::read_regular_file(path, MAX_LOG_BYTES)?;
    read_log_bytes(&bytes).map_err(|msg| Error::Runtime(format!("{}: {msg}", path.display())))
}

/// Record opcodes of the MCAP specification (0x01..=0x0F); anything else is damage in our logs.
fn known_opcode(op: u8) -> bool {
    (op::HEADER..=op::DATA_END).contains(&op)
}

/// The record framed at `pos`: opcode, body and the position after it, when its declared length
/// fits in the bytes that follow (every declared size is bounded by what the file holds).
fn frame(bytes: &[u8], pos: usize) -> Option<(u8, &[u8], usize)> {
    let head = bytes.get(pos..pos.checked_add(9)?)?;
    let len = u64::from_le_bytes(head[1..9].try_into().ok()?);
    let start = pos + 9;
    let len = usize::try_from(len).ok()?;
    let end = start.checked_add(len)?;
    let body = bytes.get(start..end)?;
    Some((head[0], body, end))
}

/// Reads the fields of one record body, checking every declared length against the bytes left
/// before allocating anything (the `mcap` crate's parser allocates a declared string length of up
/// to 4 GiB first, which aborts the process on a damaged file).
struct Fields<'a> {
    body: &'a [u8],
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.body.len() {
            return None;
        }
        let (head, rest) = self.body.split_at(n);
        self.body = rest;
        Some(head)
    }
    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn string(&mut self) -> Option<String> {
        let n = self.u32()? as usize;
        String::from_utf8(self.take(n)?.to_vec()).ok()
    }
    /// A `map<string, string>` (u32 byte length, then key/value pairs).
    fn string_map(&mut self) -> Option<BTreeMap<String, String>> {
        let n = self.u32()? as usize;
        let mut inner = Fields {
            body: self.take(n)?,
        };
        let mut map = BTreeMap::new();
        while !inner.body.is_empty() {
            let k = inner.string()?;
            let v = inner.string()?;
            if map.insert(k, v).is_some() {
                return None;
            }
        }
        Some(map)
    }
}

/// A message record's header fields.
#[derive(Clone, Copy, Debug)]
struct MessageHeader {
    channel_id: u16,
    sequence: u32,
    log_time: u64,
}

/// A chunk record's header fields.
struct ChunkHeader {
    uncompressed_size: u64,
    uncompressed_crc: u32,
    compression: String,
}

/// The records the reader uses, parsed with bounds.
enum Record<'a> {
    Channel {
        id: u16,
        topic: String,
    },
    Message {
        header: MessageHeader,
        data: &'a [u8],
    },
    Chunk {
        header: ChunkHeader,
        data: &'a [u8],
    },
    Metadata {
        name: String,
        map: BTreeMap<String, String>,
    },
    Statistics {
        messages: u64,
        chunks: u32,
    },
    Footer,
}

fn parse_record(opcode: u8, body: &[u8]) -> Option<Record<'_>> {
    let mut f = Fields { body };
    Some(match opcode {
        op::CHANNEL => {
            let id = f.u16()?;
            let _schema_id = f.u16()?;
            let topic = f.string()?;
            let _encoding = f.string()?;
            f.string_map()?;
            Record::Channel { id, topic }
        }
        op::MESSAGE => {
            let channel_id = f.u16()?;
            let sequence = f.u32()?;
            let log_time = f.u64()?;
            let _publish_time = f.u64()?;
            Record::Message {
                header: MessageHeader {
                    channel_id,
                    sequence,
                    log_time,
                },
                data: f.body,
            }
        }
        op::CHUNK => {
            let _start = f.u64()?;
            let _end = f.u64()?;
            let uncompressed_size = f.u64()?;
            let uncompressed_crc = f.u32()?;
            let compression = f.string()?;
            let compressed_size = usize::try_from(f.u64()?).ok()?;
            let data = f.take(compressed_size)?;
            Record::Chunk {
                header: ChunkHeader {
                    uncompressed_size,
                    uncompressed_crc,
                    compression,
                },
                data,
            }
        }
        op::METADATA => {
            let name = f.string()?;
            let map = f.string_map()?;
            Record::Metadata { name, map }
        }
        op::STATISTICS => {
            let messages = f.u64()?;
            let _schemas = f.u16()?;
            let _channels = f.u32()?;
            let _attachments = f.u32()?;
            let _metadata = f.u32()?;
            let chunks = f.u32()?;
            Record::Statistics { messages, chunks }
        }
        op::FOOTER => {
            f.take(20)?;
            Record::Footer
        }
        _ => return None,
    })
}

/// zstd cannot expand data by more than this factor (a 128 KiB block needs at least 4 bytes), so a
/// chunk declaring a larger uncompressed size is damaged, whatever its header says.
const ZSTD_MAX_RATIO: u64 = 1 << 15;
/// Largest uncompressed chunk accepted (our writer's are `log.chunk_size_kb`, at most 64 MiB).
const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// Decompresses a chunk's records, never allocating more than the data can really expand to, and
/// checks the declared size and CRC.
fn decode_chunk(header: &ChunkHeader, data: &[u8]) -> std::result::Result<Vec<u8>, String> {
    let declared = header.uncompressed_size;
    let limit = match header.compression.as_str() {
        "" => data.len() as u64,
        "zstd" => (data.len() as u64).saturating_mul(ZSTD_MAX_RATIO),
        other => return Err(format!("unsupported chunk compression `{other}`")),
    }
    .min(MAX_CHUNK_BYTES);
    if declared > limit {
        return Err(format!(
            "chunk declares {declared} uncompressed bytes, more than its {} bytes can hold",
            data.len()
        ));
    }
    let out = if header.compression.is_empty() {
        data.to_vec()
    } else {
        use std::io::Read;
        let decoder =
            zstd::stream::read::Decoder::with_buffer(data).map_err(|e| format!("zstd: {e}"))?;
        let mut out = Vec::new();
        decoder
            .take(declared + 1)
            .read_to_end(&mut out)
            .map_err(|e| format!("zstd: {e}"))?;
        out
    };
    if out.len() as u64 != declared {
        return Err(format!(
            "chunk holds {} bytes, not the declared {declared}",
            out.len()
        ));
    }
    if header.uncompressed_crc != 0 && crc32fast::hash(&out) != header.uncompressed_crc {
        return Err("chunk CRC mismatch".into());
    }
    Ok(out)
}

/// One message read from a chunk or the data section.
type RawMessage = (MessageHeader, Vec<u8>);

/// The channels and messages of a decompressed chunk; any damage loses the whole chunk.
fn chunk_records(
    records: &[u8],
    channels: &mut Vec<(u16, String)>,
) -> std::result::Result<Vec<RawMessage>, String> {
    let mut messages = Vec::new();
    let mut pos = 0;
    while pos < records.len() {
        let (opcode, body, next) = frame(records, pos)
            .ok_or_else(|| format!("record at chunk byte {pos} overruns the chunk"))?;
        match opcode {
            op::CHANNEL | op::MESSAGE => {
                match parse_record(opcode, body)
                    .ok_or_else(|| format!("malformed record at chunk byte {pos}"))?
                {
                    Record::Channel { id, topic } => channels.push((id, topic)),
                    Record::Message { header, data } => messages.push((header, data.to_vec())),
                    _ => {}
                }
            }
            op::SCHEMA => {}
            other => return Err(format!("unexpected record 0x{other:02x} in a chunk")),
        }
        pos = next;
    }
    Ok(messages)
}

/// What one record at a position turned out to be.
enum Parsed<'a> {
    Chunk(Vec<(u16, String)>, Vec<RawMessage>),
    /// A chunk whose framing is sound but whose content is damaged.
    BadChunk(String),
    Other(Record<'a>),
    /// A record we do not need (indexes, schemas, attachments, ...): framing checked only.
    Skipped,
}

/// Parses the record framed at `pos`; `None` when it is not a well-formed record of a known kind.
fn parse_at(bytes: &[u8], pos: usize) -> Option<(Parsed<'_>, usize)> {
    let (opcode, body, next) = frame(bytes, pos)?;
    if !known_opcode(opcode) {
        return None;
    }
    let parsed = match opcode {
        op::CHUNK => match parse_record(opcode, body)? {
            Record::Chunk { header, data } => {
                let mut channels = Vec::new();
                match decode_chunk(&header, data)
                    .and_then(|records| chunk_records(&records, &mut channels))
                {
                    Ok(messages) => Parsed::Chunk(channels, messages),
                    Err(e) => Parsed::BadChunk(e),
                }
            }
            _ => return None,
        },
        op::CHANNEL | op::MESSAGE | op::METADATA | op::STATISTICS | op::FOOTER => {
            Parsed::Other(parse_record(opcode, body)?)
        }
        _ => Parsed::Skipped,
    };
    Some((parsed, next))
}

/// After damage at `from - 1`: the first later position where a well-formed record starts that is
/// followed by another record's plausible header, the end magic, or the end of the file.
fn resync(bytes: &[u8], from: usize) -> Option<usize> {
    (from..bytes.len()).find(|&q| {
        if !bytes.get(q).is_some_and(|&o| known_opcode(o)) {
            return false;
        }
        let Some((parsed, next)) = parse_at(bytes, q) else {
            return false;
        };
        if matches!(parsed, Parsed::BadChunk(_)) {
            return false;
        }
        next == bytes.len()
            || bytes[next..].starts_with(mcap::MAGIC)
            || frame(bytes, next).is_some_and(|(o, _, _)| known_opcode(o))
    })
}

/// [`read_log`] on bytes in memory. Damage anywhere is survived: a damaged chunk is counted lost, a
/// damaged record outside chunks is skipped by resynchronising on the next well-formed record, and
/// a cut-off tail ends the read.
pub fn read_log_bytes(bytes: &[u8]) -> std::result::Result<LogContents, String> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err("not an MCAP file (no MCAP magic at the start)".into());
    }
    let mut out = LogContents::default();
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut expected_messages = None;
    let mut expected_chunks = None;
    let mut footer = false;
    let mut pos = mcap::MAGIC.len();
    while pos < bytes.len() && !footer {
        let Some((parsed, next)) = parse_at(bytes, pos) else {
            if bytes[pos..] == *mcap::MAGIC {
                break;
            }
            match resync(bytes, pos + 1) {
                Some(q) => {
                    out.problem.get_or_insert(format!(
                        "damaged record at byte {pos}, {} bytes skipped",
                        q - pos
                    ));
                    pos = q;
                    continue;
                }
                None => {
                    // Nothing well-formed follows: a cut-off tail (usually inside a chunk).
                    if bytes[pos] == op::CHUNK {
                        out.chunks_lost += 1;
                    }
                    out.problem.get_or_insert(format!(
                        "file ends mid-record (damaged or cut off at byte {pos} of {})",
                        bytes.len()
                    ));
                    break;
                }
            }
        };
        pos = next;
        match parsed {
            Parsed::Chunk(channels, messages) => {
                out.chunks_read += 1;
                topics.extend(channels);
                for (h, data) in messages {
                    out.messages.push(LoggedMessage {
                        topic: topics.get(&h.channel_id).cloned().unwrap_or_default(),
                        log_time_ns: h.log_time,
                        sequence: h.sequence,
                        data,
                    });
                }
            }
            Parsed::BadChunk(e) => {
                out.chunks_lost += 1;
                out.problem.get_or_insert(format!("damaged chunk ({e})"));
            }
            Parsed::Skipped => {}
            Parsed::Other(record) => match record {
                Record::Channel { id, topic } => {
                    topics.insert(id, topic);
                }
                Record::Message { header, data } => out.messages.push(LoggedMessage {
                    topic: topics.get(&header.channel_id).cloned().unwrap_or_default(),
                    log_time_ns: header.log_time,
                    sequence: header.sequence,
                    data: data.to_vec(),
                }),
                Record::Metadata { name, map } if name == RUN_METADATA => {
                    out.identity = RunIdentity::from_map(&map);
                }
                Record::Metadata { name, map } if name == RESULT_METADATA => {
                    out.result = map.get("result").and_then(|j| serde_json::from_str(j).ok());
                }
                Record::Statistics { messages, chunks } => {
                    expected_messages = Some(messages);
                    expected_chunks = Some(u64::from(chunks));
                }
                Record::Footer => footer = true,
                _ => {}
            },
        }
    }
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
            out.messages_lost = max_seq.map_or(0, |s| (s + 1).saturating_sub(decoded));
        }
    }
    if out.messages_lost > 0 && out.problem.is_none() {
        out.problem = Some(format!("{} messages missing", out.messages_lost));
    }
    // A log without the run's identity (or its result) cannot be verified or trusted: a loss.
    if out.identity.is_none() {
        out.problem
            .get_or_insert("the run identity metadata is missing".into());
    } else if out.result.is_none() && footer {
        out.problem
            .get_or_insert("the run result metadata is missing".into());
    }
    out.complete = footer && out.identity.is_some() && out.result.is_some();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// A small valid log: identity and result metadata and `n` messages in 1 KiB zstd chunks.
    fn small_log(n: u32) -> Vec<u8> {
        let mut w = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(1024))
            .create(std::io::Cursor::new(Vec::new()))
            .unwrap();
        let schema = w.add_schema("s", "jsonschema", b"{}").unwrap();
        let ch = w
            .add_channel(schema, "/robot/pose", "json", &BTreeMap::new())
            .unwrap();
        let id = RunIdentity {
            scene_path: "s.obj".into(),
            scene_abs_path: String::new(),
            scene_hash: "h".into(),
            planner: "greedy".into(),
            seed: 1,
            version: "0".into(),
            config_hash: "c".into(),
            config_toml: String::new(),
            spawn: String::new(),
        };
        w.write_metadata(&mcap::records::Metadata {
            name: RUN_METADATA.into(),
            metadata: id.to_map(),
        })
        .unwrap();
        for i in 0..n {
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i,
                log_time: u64::from(i) * 100,
                publish_time: u64::from(i) * 100,
            };
            let data = format!(
                "{{\"i\": {i}, \"pad\": \"{}\"}}",
                "x".repeat(60 + (i as usize * 7) % 50)
            );
            w.write_to_known_channel(&header, data.as_bytes()).unwrap();
        }
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    /// (opcode, start, end) of the top-level records.
    fn records(bytes: &[u8]) -> Vec<(u8, usize, usize)> {
        let mut out = Vec::new();
        let mut pos = mcap::MAGIC.len();
        while let Some((op, _, next)) = frame(bytes, pos) {
            out.push((op, pos, next));
            pos = next;
        }
        out
    }

    /// A real run log (identity, result, 4 KiB chunks), the fuzz harness's seed.
    fn real_log() -> Vec<u8> {
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz_seed_run.mcap"))
            .unwrap()
    }

    #[test]
    fn mcap_chunk_size_bounded() {
        let good = real_log();
        let log = read_log_bytes(&good).unwrap();
        let total = log.messages.len();
        assert!(total > 50, "{total}");
        assert!(!log.is_damaged(), "{:?}", log.problem);
        let chunks: Vec<_> = records(&good)
            .into_iter()
            .filter(|r| r.0 == op::CHUNK)
            .collect();
        assert!(chunks.len() >= 3, "{} chunks", chunks.len());
        // The declared uncompressed size (after the opcode, length, start and end times) of the
        // second chunk, made absurd: the size seen in the wild, and the largest.
        let at = chunks[1].1 + 9 + 16;
        for declared in [349_644_714_409_993u64, u64::MAX, 3] {
            let mut bad = good.clone();
            bad[at..at + 8].copy_from_slice(&declared.to_le_bytes());
            let log = read_log_bytes(&bad).unwrap();
            assert_eq!(log.chunks_lost, 1, "{declared}");
            assert_eq!(log.chunks_read, chunks.len() as u64 - 1, "{declared}");
            assert!(log.complete, "the summary after the damage is read");
            assert!(log.messages_lost > 0 && log.messages.len() < total);
            let problem = log.problem.unwrap();
            assert!(problem.starts_with("damaged chunk ("), "{problem}");
        }
    }

    #[test]
    fn damaged_opcode_between_chunks_resyncs() {
        let good = real_log();
        let recs = records(&good);
        let chunks = recs.iter().filter(|r| r.0 == op::CHUNK).count();
        // The opcode of the second chunk becomes an unknown one: that chunk is lost, every other
        // one and the summary are still read (the old reader stopped here).
        let second = recs.iter().filter(|r| r.0 == op::CHUNK).nth(1).unwrap().1;
        let mut bad = good.clone();
        bad[second] = 0x7f;
        let log = read_log_bytes(&bad).unwrap();
        assert_eq!(log.chunks_read, chunks as u64 - 1);
        assert_eq!(log.chunks_lost, 1);
        assert!(log.complete);
        assert!(log
            .problem
            .unwrap()
            .starts_with(&format!("damaged record at byte {second}")));
    }

    #[test]
    fn log_without_identity_is_incomplete() {
        let good = small_log(10);
        let mut stripped = good[..mcap::MAGIC.len()].to_vec();
        let recs = records(&good);
        for &(op, a, b) in &recs {
            if op != op::METADATA && op != op::METADATA_INDEX {
                stripped.extend_from_slice(&good[a..b]);
            }
        }
        stripped.extend_from_slice(&good[recs.last().unwrap().2..]);
        let log = read_log_bytes(&stripped).unwrap();
        assert_eq!(log.messages.len(), 10);
        assert!(log.identity.is_none() && !log.complete && log.is_damaged());
        assert_eq!(
            log.problem.as_deref(),
            Some("the run identity metadata is missing")
        );
    }
}
