//! MCAP recordings of a stack's topics, as pure code (no iceoryx2): what `mta record` writes and
//! `mta replay` reads.
//!
//! One channel per topic, named as the iceoryx2 service (`mtanet/observation`, ...), each with a
//! JSON schema; messages are JSON (`message_encoding = "json"`), so Foxglove and the `mcap` CLI
//! show their fields and plot them. Each message also carries `raw`: the `#[repr(C)]` message's
//! exact bytes in base64, which is what replay decodes, so a replayed observation is bit for bit
//! the one recorded. The camera also goes to `mtanet/camera` as a `foxglove.RawImage` (mono8)
//! for Foxglove's image panel. Messages are stamped (log and publish time) with their own
//! `CLOCK_MONOTONIC` stamp. Chunks are zstd-compressed and closed every `flush`, so a recorder
//! killed mid-run leaves a file readable up to its last flush.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use anyhow::{Context, bail};
use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use mtanet_ipc::{
    Command, CommandSource, IMAGE_HEIGHT, IMAGE_WIDTH, Observation, ReplayChunk, TrainerStatus,
    WeightsHeader, names,
};
use serde_json::{Value, json};

pub const CAMERA: &str = "mtanet/camera";

/// A message read back from a recording.
#[derive(Debug, Clone)]
pub enum Recorded {
    Observation(Observation),
    Command(Command),
    Replay(Box<ReplayChunk>),
    /// The header, and the checkpoint's bytes when they were recorded (`--weight-blobs`).
    Weights(WeightsHeader, Option<Vec<u8>>),
    /// Recorded for a person to look at (Foxglove); replay has no use for it.
    #[allow(dead_code)]
    TrainerStatus(TrainerStatus),
}

/// The topics a recording can hold (`--topics`), by their iceoryx2 service names' last part.
pub const TOPICS: [&str; 5] = [
    "observation",
    "command",
    "replay",
    "weights",
    "trainer_status",
];

fn f(v: f32) -> Value {
    // NaN and inf have no JSON form: null (raw keeps the exact value).
    if v.is_finite() { json!(v) } else { Value::Null }
}

fn fs(v: &[f32]) -> Value {
    Value::Array(v.iter().map(|&x| f(x)).collect())
}

fn raw<T: bytemuck::Pod>(m: &T) -> Value {
    json!(B64.encode(bytemuck::bytes_of(m)))
}

fn schema(title: &str, props: &[(&str, &str)]) -> Vec<u8> {
    let mut p = serde_json::Map::new();
    for (name, ty) in props {
        let v = match *ty {
            "numbers" => json!({"type": "array", "items": {"type": ["number", "null"]}}),
            "bytes" => json!({"type": "string", "contentEncoding": "base64"}),
            "object" => json!({"type": "object"}),
            t => json!({"type": t}),
        };
        p.insert(name.to_string(), v);
    }
    serde_json::to_vec(&json!({"title": title, "type": "object", "properties": p}))
        .expect("a schema serialises")
}

/// Writes a recording; one call per message, `flush` at least once a second.
pub struct RecordingWriter<W: Write + Seek> {
    out: mcap::Writer<W>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    /// Messages written per channel.
    pub counts: BTreeMap<&'static str, u64>,
}

impl RecordingWriter<BufWriter<File>> {
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        Self::new(BufWriter::new(file))
    }
}

impl<W: Write + Seek> RecordingWriter<W> {
    pub fn new(w: W) -> anyhow::Result<Self> {
        let mut out = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("")
            .create(w)?;
        let mut channels = BTreeMap::new();
        let specs: [(&'static str, &str, Vec<u8>); 6] = [
            (
                names::OBSERVATION,
                "mtanet.Observation",
                schema(
                    "mtanet.Observation",
                    &[
                        ("stamp_ns", "integer"),
                        ("step", "integer"),
                        ("sim_time_s", "number"),
                        ("image", "numbers"),
                        ("wheel_velocity", "numbers"),
                        ("command", "numbers"),
                        ("line_sensors", "numbers"),
                        ("episode", "integer"),
                        ("lockstep", "integer"),
                        ("truth", "object"),
                        ("raw", "bytes"),
                    ],
                ),
            ),
            (CAMERA, "foxglove.RawImage", raw_image_schema()),
            (
                names::COMMAND,
                "mtanet.Command",
                schema(
                    "mtanet.Command",
                    &[
                        ("stamp_ns", "integer"),
                        ("step", "integer"),
                        ("model_version", "integer"),
                        ("wheel_velocity", "numbers"),
                        ("source", "string"),
                        ("compute_us", "number"),
                        ("model_error_ratio", "number"),
                        ("probe", "number"),
                        ("raw", "bytes"),
                    ],
                ),
            ),
            (
                names::REPLAY,
                "mtanet.ReplayChunk",
                schema(
                    "mtanet.ReplayChunk",
                    &[
                        ("seq", "integer"),
                        ("first_step", "integer"),
                        ("len", "integer"),
                        ("episode", "integer"),
                        ("pace", "number"),
                        ("raw", "bytes"),
                    ],
                ),
            ),
            (
                names::WEIGHTS,
                "mtanet.Weights",
                schema(
                    "mtanet.Weights",
                    &[
                        ("version", "integer"),
                        ("train_step", "integer"),
                        ("len", "integer"),
                        ("loss", "number"),
                        ("probe", "number"),
                        ("raw", "bytes"),
                        ("blob", "bytes"),
                    ],
                ),
            ),
            (
                names::TRAINER_STATUS,
                "mtanet.TrainerStatus",
                schema(
                    "mtanet.TrainerStatus",
                    &[
                        ("updates", "integer"),
                        ("chunks_received", "integer"),
                        ("chunks_lost", "integer"),
                        ("sequences", "integer"),
                        ("training", "integer"),
                        ("raw", "bytes"),
                    ],
                ),
            ),
        ];
        for (topic, name, data) in specs {
            let schema = out.add_schema(name, "jsonschema", &data)?;
            let id = out.add_channel(schema, topic, "json", &BTreeMap::new())?;
            channels.insert(topic, id);
        }
        Ok(Self {
            out,
            channels,
            sequence: 0,
            counts: BTreeMap::new(),
        })
    }

    fn write(&mut self, topic: &'static str, stamp_ns: u64, v: &Value) -> anyhow::Result<()> {
        let channel_id = self.channels[topic];
        self.sequence = self.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: stamp_ns,
            publish_time: stamp_ns,
        };
        self.out
            .write_to_known_channel(&header, &serde_json::to_vec(v)?)?;
        *self.counts.entry(topic).or_default() += 1;
        Ok(())
    }

    /// The observation, and its camera frame as a `foxglove.RawImage`.
    pub fn observation(&mut self, o: &Observation) -> anyhow::Result<()> {
        let t = &o.truth;
        let v = json!({
            "stamp_ns": o.stamp_ns, "step": o.step, "sim_time_s": o.sim_time_s,
            "image": fs(&o.image), "wheel_velocity": fs(&o.wheel_velocity),
            "command": fs(&o.command), "line_sensors": o.line_sensors,
            "episode": o.episode, "lockstep": o.lockstep,
            "truth": {"x_m": t.x_m, "y_m": t.y_m, "yaw_rad": t.yaw_rad, "track_s_m": t.track_s_m,
                      "lateral_m": t.lateral_m, "laps": t.laps, "on_line": t.on_line},
            "raw": raw(o),
        });
        self.write(names::OBSERVATION, o.stamp_ns, &v)?;
        let grey: Vec<u8> = o
            .image
            .iter()
            .map(|&g| (g.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        let image = json!({
            "timestamp": {"sec": o.stamp_ns / 1_000_000_000, "nsec": o.stamp_ns % 1_000_000_000},
            "frame_id": "camera_mid", "width": IMAGE_WIDTH, "height": IMAGE_HEIGHT,
            "encoding": "mono8", "step": IMAGE_WIDTH, "data": B64.encode(grey),
        });
        self.write(CAMERA, o.stamp_ns, &image)
    }

    pub fn command(&mut self, c: &Command) -> anyhow::Result<()> {
        let source = CommandSource::from_u32(c.source).map_or("?", CommandSource::name);
        let v = json!({
            "stamp_ns": c.stamp_ns, "step": c.step, "model_version": c.model_version,
            "wheel_velocity": fs(&c.wheel_velocity), "source": source,
            "compute_us": c.compute_ns as f64 / 1e3, "model_error_ratio": f(c.model_error_ratio),
            "probe": f(c.probe), "raw": raw(c),
        });
        self.write(names::COMMAND, c.stamp_ns, &v)
    }

    pub fn replay(&mut self, c: &ReplayChunk) -> anyhow::Result<()> {
        let v = json!({
            "seq": c.seq, "first_step": c.first_step, "len": c.len, "episode": c.episode,
            "pace": f(c.pace), "raw": raw(c),
        });
        self.write(names::REPLAY, c.stamp_ns, &v)
    }

    pub fn weights(&mut self, h: &WeightsHeader, blob: Option<&[u8]>) -> anyhow::Result<()> {
        let mut v = json!({
            "version": h.version, "train_step": h.train_step, "len": h.len, "loss": f(h.loss),
            "probe": f(h.probe), "raw": raw(h),
        });
        if let Some(b) = blob {
            v["blob"] = json!(B64.encode(b));
        }
        self.write(names::WEIGHTS, h.stamp_ns, &v)
    }

    pub fn trainer_status(&mut self, s: &TrainerStatus) -> anyhow::Result<()> {
        let v = json!({
            "updates": s.updates, "chunks_received": s.chunks_received,
            "chunks_lost": s.chunks_lost, "sequences": s.sequences, "training": s.training,
            "raw": raw(s),
        });
        self.write(names::TRAINER_STATUS, s.stamp_ns, &v)
    }

    /// Closes the current chunk and flushes it to the file: a crash after this loses nothing
    /// written before it.
    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.out.flush()?;
        Ok(())
    }

    /// Writes the summary and footer (indexes for seeking readers such as Foxglove).
    pub fn finish(mut self) -> anyhow::Result<()> {
        self.out.finish()?;
        Ok(())
    }
}

fn raw_image_schema() -> Vec<u8> {
    serde_json::to_vec(&json!({
        "title": "foxglove.RawImage",
        "type": "object",
        "properties": {
            "timestamp": {"type": "object", "properties": {
                "sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
            "frame_id": {"type": "string"},
            "width": {"type": "integer"},
            "height": {"type": "integer"},
            "encoding": {"type": "string"},
            "step": {"type": "integer"},
            "data": {"type": "string", "contentEncoding": "base64"}
        }
    }))
    .expect("a schema serialises")
}

/// What a recording holds, in the order of its stamps.
#[derive(Debug, Default)]
pub struct Reading {
    pub messages: Vec<(u64, Recorded)>,
    /// Why reading stopped early (a truncated or damaged file): what came before is kept.
    pub damaged: Option<String>,
}

fn decode_raw<T: bytemuck::Pod>(topic: &str, v: &Value) -> anyhow::Result<T> {
    let s = v["raw"]
        .as_str()
        .with_context(|| format!("a {topic} message without its raw bytes"))?;
    let bytes = B64
        .decode(s)
        .with_context(|| format!("{topic}: raw is not base64"))?;
    if bytes.len() != std::mem::size_of::<T>() {
        bail!(
            "{topic}: {} raw bytes, this build's message has {} (recorded by another version?)",
            bytes.len(),
            std::mem::size_of::<T>()
        );
    }
    Ok(bytemuck::pod_read_unaligned(&bytes))
}

fn decode(topic: &str, data: &[u8]) -> anyhow::Result<Option<Recorded>> {
    if topic == CAMERA {
        return Ok(None);
    }
    let v: Value = serde_json::from_slice(data).with_context(|| format!("{topic}: not JSON"))?;
    Ok(Some(match topic {
        names::OBSERVATION => Recorded::Observation(decode_raw(topic, &v)?),
        names::COMMAND => Recorded::Command(decode_raw(topic, &v)?),
        names::REPLAY => Recorded::Replay(Box::new(decode_raw(topic, &v)?)),
        names::TRAINER_STATUS => Recorded::TrainerStatus(decode_raw(topic, &v)?),
        names::WEIGHTS => {
            let blob = match v["blob"].as_str() {
                Some(b) => Some(B64.decode(b).context("weights: blob is not base64")?),
                None => None,
            };
            Recorded::Weights(decode_raw(topic, &v)?, blob)
        }
        _ => return Ok(None),
    }))
}

/// Reads every message it can: a truncated or damaged file gives the messages before the damage
/// and says where reading stopped (`damaged`); a file that is no MCAP at all is an error.
pub fn read(path: &Path) -> anyhow::Result<Reading> {
    let buf = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let stream =
        mcap::MessageStream::new_with_options(&buf, mcap::read::Options::IgnoreEndMagic.into())
            .with_context(|| format!("{} is not an MCAP recording", path.display()))?;
    let mut r = Reading::default();
    for (i, m) in stream.enumerate() {
        let m = match m {
            Ok(m) => m,
            Err(e) => {
                r.damaged = Some(format!(
                    "{}: unreadable after {i} messages ({e}); replaying what came before",
                    path.display()
                ));
                break;
            }
        };
        match decode(&m.channel.topic, &m.data) {
            Ok(Some(rec)) => r.messages.push((m.log_time, rec)),
            Ok(None) => {}
            Err(e) => {
                r.damaged = Some(format!("{}: message {i}: {e:#}", path.display()));
                break;
            }
        }
    }
    if let (true, Some(why)) = (r.messages.is_empty(), &r.damaged) {
        bail!("{why}: nothing in it can be replayed");
    }
    // One publisher per topic writes in order; across topics the stamps give the order.
    r.messages.sort_by_key(|m| m.0);
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(step: u64) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.stamp_ns = 1_000 + step * 20_000_000;
        o.step = step;
        o.sim_time_s = step as f64 * 0.02;
        for (i, p) in o.image.iter_mut().enumerate() {
            // Values JSON's shortest decimal form must carry exactly.
            *p = (i as f32 * 0.1 + step as f32 / 3.0).fract();
        }
        o.command = [8.123_457, f32::MIN_POSITIVE];
        o.truth.lateral_m = -0.001_234_567_89;
        o
    }

    fn cmd(step: u64) -> Command {
        let mut c: Command = bytemuck::Zeroable::zeroed();
        c.stamp_ns = 2_000 + step * 20_000_000;
        c.step = step;
        c.wheel_velocity = [7.5, 1.0 / 3.0];
        c.model_error_ratio = f32::NAN;
        c
    }

    fn write(path: &Path, n: u64, flush_every: u64) {
        let mut w = RecordingWriter::create(path).unwrap();
        for s in 0..n {
            w.observation(&obs(s)).unwrap();
            w.command(&cmd(s)).unwrap();
            if s % flush_every == flush_every - 1 {
                w.flush().unwrap();
            }
        }
        let h = WeightsHeader {
            version: 3,
            len: 4,
            stamp_ns: 5,
            ..Default::default()
        };
        w.weights(&h, Some(&[1, 2, 3, 4])).unwrap();
        w.finish().unwrap();
    }

    #[test]
    fn round_trips_every_message_bit_for_bit_in_stamp_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        write(&path, 50, 10);
        let r = read(&path).unwrap();
        assert!(r.damaged.is_none(), "{:?}", r.damaged);
        assert_eq!(r.messages.len(), 101);
        let Recorded::Weights(h, Some(blob)) = &r.messages[0].1 else {
            panic!("the weights (stamp 5) come first: {:?}", r.messages[0]);
        };
        assert_eq!((h.version, blob.as_slice()), (3, &[1u8, 2, 3, 4][..]));
        let observations: Vec<&Observation> = r
            .messages
            .iter()
            .filter_map(|m| match &m.1 {
                Recorded::Observation(o) => Some(o),
                _ => None,
            })
            .collect();
        assert_eq!(observations.len(), 50);
        for (s, o) in observations.iter().enumerate() {
            assert_eq!(bytemuck::bytes_of(*o), bytemuck::bytes_of(&obs(s as u64)));
        }
        let c = r.messages.iter().find_map(|m| match &m.1 {
            Recorded::Command(c) => Some(*c),
            _ => None,
        });
        let c = c.unwrap();
        assert!(c.model_error_ratio.is_nan(), "NaN survives through raw");
        assert_eq!(bytemuck::bytes_of(&c), bytemuck::bytes_of(&cmd(0)));
    }

    #[test]
    fn a_truncated_recording_replays_what_is_readable_and_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        write(&path, 400, 100);
        let full = std::fs::read(&path).unwrap();
        // A recorder killed mid-write: the file ends inside the last chunks.
        let cut = dir.path().join("cut.mcap");
        std::fs::write(&cut, &full[..full.len() * 2 / 3]).unwrap();
        let r = read(&cut).unwrap();
        let n = r.messages.len();
        assert!(r.damaged.is_some(), "the damage is reported");
        assert!(
            (200..800).contains(&n),
            "the flushed chunks before the cut are read: {n}"
        );
        assert!(
            r.damaged.as_ref().unwrap().contains("cut.mcap"),
            "{:?}",
            r.damaged
        );
        // Not an MCAP file at all: an error naming it.
        let junk = dir.path().join("junk.mcap");
        std::fs::write(&junk, b"not a recording").unwrap();
        let e = read(&junk).unwrap_err();
        assert!(format!("{e:#}").contains("junk.mcap"), "{e:#}");
    }
}
