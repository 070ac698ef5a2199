//! MCAP recordings of a stack's topics, as pure code (no iceoryx2): what `mta record` writes and
//! `mta replay` reads.
//!
//! One channel per topic, named as the iceoryx2 service (`mtanet/observation`, ...), each with a
//! JSON schema; messages are JSON (`message_encoding = "json"`), so Foxglove and the `mcap` CLI
//! show their fields and plot them. Each message also carries `raw`: the `#[repr(C)]` message's
//! exact bytes in base64, which is what replay decodes, so a replayed observation is bit for bit
//! the one recorded. The camera also goes to `mtanet/camera` as a `foxglove.RawImage` (mono8)
//! for Foxglove's image panel. Messages are stamped (log and publish time) with their own
//! `CLOCK_MONOTONIC` stamp plus the recording's offset from it to the Unix epoch, taken when the
//! recording starts and kept in its `mtanet.clock` metadata, so Foxglove shows real dates and the
//! monotonic stamps can be recovered. Chunks are zstd-compressed and closed every `flush`, so a recorder
//! killed mid-run leaves a file readable up to its last flush.

mod read;
#[cfg(test)]
mod tests;

pub use read::{Reading, read};

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use anyhow::Context;
use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use mtanet_ipc::{
    Command, CommandSource, IMAGE_HEIGHT, IMAGE_WIDTH, Observation, PLAN_SEGMENTS, ReplayChunk,
    TrainerStatus, WeightsHeader, names,
};
use serde_json::{Value, json};

pub const CAMERA: &str = "mtanet/camera";
/// The metadata record holding the clock offset of the message times.
pub const CLOCK_METADATA: &str = "mtanet.clock";

/// Unix time minus `CLOCK_MONOTONIC` now, in ns: what turns a message's stamp into a date.
pub fn monotonic_to_unix_offset_ns() -> u64 {
    let unix = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    unix.saturating_sub(mtanet_ipc::stamp::monotonic_ns())
}

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
    /// Unix time minus `CLOCK_MONOTONIC`, ns, when the recording started.
    clock_offset_ns: u64,
    /// Messages written per channel.
    pub counts: BTreeMap<&'static str, u64>,
}

impl RecordingWriter<BufWriter<File>> {
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        Self::new(BufWriter::new(file))
    }
}

/// Each message topic's JSON channel: (topic, schema name, fields and their JSON types).
const MESSAGE_CHANNELS: [(&str, &str, &[(&str, &str)]); 5] = [
    (
        names::OBSERVATION,
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
    (
        names::COMMAND,
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
            ("plan_first_step", "integer"),
            ("plan_segment_steps", "integer"),
            ("plan", "numbers"),
            ("raw", "bytes"),
        ],
    ),
    (
        names::REPLAY,
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
    (
        names::WEIGHTS,
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
    (
        names::TRAINER_STATUS,
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
];

/// Every channel of a recording, in the order they are added: (topic, schema name, JSON schema);
/// the camera's Foxglove image channel comes second, after the observations it is cut from.
fn channel_schemas() -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let mut out: Vec<_> = MESSAGE_CHANNELS
        .iter()
        .map(|&(topic, name, fields)| (topic, name, schema(name, fields)))
        .collect();
    out.insert(1, (CAMERA, "foxglove.RawImage", raw_image_schema()));
    out
}

impl<W: Write + Seek> RecordingWriter<W> {
    pub fn new(w: W) -> anyhow::Result<Self> {
        let mut out = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("")
            .create(w)?;
        let clock_offset_ns = monotonic_to_unix_offset_ns();
        out.write_metadata(&mcap::records::Metadata {
            name: CLOCK_METADATA.into(),
            metadata: BTreeMap::from([(
                "monotonic_to_unix_offset_ns".to_string(),
                clock_offset_ns.to_string(),
            )]),
        })?;
        let mut channels = BTreeMap::new();
        for (topic, name, data) in channel_schemas() {
            let schema = out.add_schema(name, "jsonschema", &data)?;
            let id = out.add_channel(schema, topic, "json", &BTreeMap::new())?;
            channels.insert(topic, id);
        }
        Ok(Self {
            out,
            channels,
            sequence: 0,
            clock_offset_ns,
            counts: BTreeMap::new(),
        })
    }

    fn write(&mut self, topic: &'static str, stamp_ns: u64, v: &Value) -> anyhow::Result<()> {
        let channel_id = self.channels[topic];
        self.sequence = self.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: stamp_ns.saturating_add(self.clock_offset_ns),
            publish_time: stamp_ns.saturating_add(self.clock_offset_ns),
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
            "probe": f(c.probe), "plan_first_step": c.plan_first_step,
            "plan_segment_steps": c.plan_segment_steps,
            "plan": fs(c.plan[..(c.plan_len as usize).min(PLAN_SEGMENTS)].as_flattened()),
            "raw": raw(c),
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
