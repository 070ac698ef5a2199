//! Reading a recording back: every message that can be read, in stamp order.

use std::path::Path;

use anyhow::{Context, bail};
use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use mtanet_ipc::names;
use serde_json::Value;

use super::{CAMERA, Recorded};

/// What a recording holds, in the order of its stamps.
#[derive(Debug, Default)]
pub struct Reading {
    /// (log time: the message's stamp plus the recording's clock offset, ns; the message).
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
