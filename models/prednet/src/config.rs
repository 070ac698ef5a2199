//! Model configuration (serde, TOML). `Default` is the paper's network at the size we run it.

use serde::{Deserialize, Serialize};

/// How the action MLP's outputs become weights over the generative units of one layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionWeighting {
    /// Independent gates in (0, 1). The default: with G units a layer gets G degrees of freedom
    /// from the action, where softmax gives G - 1 (one, with the default 2 units, which cannot
    /// follow a 2-d action at a single layer).
    Sigmoid,
    /// A convex combination (weights sum to 1): units compete, R stays in the ConvLSTM's range.
    Softmax,
}

/// How the error units E_l enter the loss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorLoss {
    /// PredNet's: the mean activity of E_l (= half the mean absolute error at layer 0).
    L1,
    /// The mean of E_l squared (= the mean squared prediction error at layer 0).
    L2,
}

/// The network's shape and loss weighting. Image and action sizes are taken from the data when
/// training from a file; everything else comes from here.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelConfig {
    /// Image rows (H). Must be divisible by 2^(layers - 1) because of the 2x2 pooling.
    pub image_height: i64,
    /// Image columns (W). Same divisibility rule as `image_height`.
    pub image_width: i64,
    /// Length of the action vector a(t) (2: the two wheel velocities).
    pub action_dim: i64,
    /// Control steps per model step: the model sees every `frame_skip`-th frame, and its action
    /// is the mean wheel command over the steps in between (1: every frame, as in the paper).
    /// Part of the checkpoint, so whoever runs the model steps it at the cadence it learnt.
    pub frame_skip: i64,
    /// R channels per layer (the generative units' ConvLSTM width). Its length is the number of layers.
    pub channels: Vec<i64>,
    /// Channels of X_l / Xhat_l per layer; the first is the image's (1, grayscale).
    pub a_channels: Vec<i64>,
    /// Generative units (ConvLSTMs) per layer.
    pub gus: Vec<i64>,
    /// Leaky-integration time constant per layer (>= 1; 1 = the plain recurrent update).
    pub tau: Vec<f64>,
    /// Square kernel of every convolution (odd, padded to keep the size).
    pub kernel: i64,
    /// Subtracted from a(t) before the action MLPs (empty = none). Part of the model so that the
    /// predictor feeds raw wheel velocities; `mta train` fills it with the data's mean when empty.
    pub action_offset: Vec<f64>,
    /// a(t) - offset is divided by this (empty = 1); `mta train` fills it with the data's std.
    pub action_scale: Vec<f64>,
    /// Hidden width of each layer's action MLP.
    pub action_hidden: i64,
    /// Sigmoid or softmax weights over the generative units.
    pub action_weighting: ActionWeighting,
    /// Initial bias of each layer's Xhat conv. Positive so that relu(conv(R)) starts alive while
    /// R is near 0 (docs/measurements.md: the layer-0 ReLU died and the loss stayed flat without it).
    pub xhat_bias: Vec<f64>,
    /// Loss weight of each layer's errors (PredNet "L_0": only layer 0).
    pub layer_loss_weights: Vec<f64>,
    /// Loss weight per time step t = 0, 1, ...; steps past the end use the last entry.
    /// PredNet gives t = 0 no weight: that prediction is made from the empty state.
    pub time_loss_weights: Vec<f64>,
    /// L1 (PredNet) or L2 on the error units.
    pub error_loss: ErrorLoss,
}

impl Default for ModelConfig {
    fn default() -> Self {
        Self {
            image_height: 8,
            image_width: 12,
            action_dim: 2,
            frame_skip: 1,
            channels: vec![8, 16, 32],
            a_channels: vec![1, 8, 16],
            gus: vec![2, 2, 2],
            tau: vec![1.0, 1.3, 2.0],
            kernel: 3,
            action_offset: Vec::new(),
            action_scale: Vec::new(),
            action_hidden: 16,
            action_weighting: ActionWeighting::Sigmoid,
            xhat_bias: vec![0.5, 0.1, 0.1],
            layer_loss_weights: vec![1.0, 0.0, 0.0],
            time_loss_weights: vec![0.0, 1.0],
            error_loss: ErrorLoss::L2,
        }
    }
}

/// A configuration that cannot build a network.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A per-layer list has a different length from `channels`.
    #[error("`{key}` has {got} entries but `channels` defines {layers} layers")]
    LayerCount {
        key: &'static str,
        got: usize,
        layers: usize,
    },
    /// A value is out of its allowed range.
    #[error("`{key}` = {value}: {why}")]
    OutOfRange {
        key: &'static str,
        value: String,
        why: &'static str,
    },
    /// The image does not halve cleanly down the pooling pyramid.
    #[error("image {h}x{w} cannot be pooled 2x2 {times} times (needs both divisible by {div})")]
    NotPoolable {
        h: i64,
        w: i64,
        times: u32,
        div: i64,
    },
    /// The network does not read the frames or actions the stack sends.
    #[error("the model takes {model}, the stack sends {wire}")]
    Wire { model: String, wire: String },
    /// The TOML text does not parse into a configuration.
    #[error("invalid configuration TOML: {0}")]
    Toml(#[from] toml::de::Error),
}

impl ModelConfig {
    /// A small network (4, 6 and 8 channels) with the given taus: built and stepped in
    /// milliseconds, for tests and examples.
    pub fn small(tau: &[f64]) -> Self {
        Self {
            channels: vec![4, 6, 8],
            a_channels: vec![1, 4, 6],
            tau: tau.to_vec(),
            ..Default::default()
        }
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.channels.len()
    }

    /// (height, width) of layer `l` after `l` 2x2 poolings.
    pub fn layer_size(&self, l: usize) -> (i64, i64) {
        (self.image_height >> l, self.image_width >> l)
    }

    /// Parses and validates a TOML document holding only model keys.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        let cfg: Self = toml::from_str(text)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// The network must read the frames the simulator sends (`image`: height, width) and the
    /// commands' `action_dim` values: the predictor checks every checkpoint it is handed, the
    /// trainer its `[trainer.model]`.
    pub fn check_wire(&self, image: (usize, usize), action_dim: usize) -> Result<(), ConfigError> {
        let (h, w) = (image.0 as i64, image.1 as i64);
        if (self.image_height, self.image_width) != (h, w) {
            return Err(ConfigError::Wire {
                model: format!("{}x{} images", self.image_height, self.image_width),
                wire: format!("{h}x{w}"),
            });
        }
        if self.action_dim != action_dim as i64 {
            return Err(ConfigError::Wire {
                model: format!("{} action values", self.action_dim),
                wire: format!("{action_dim}"),
            });
        }
        Ok(())
    }

    /// Checks every rule the network relies on, naming the offending key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_layers()?;
        self.validate_action()?;
        self.validate_loss()?;
        let times = (self.layers() - 1) as u32;
        let div = 1i64 << times;
        if self.image_height % div != 0 || self.image_width % div != 0 {
            let (h, w) = (self.image_height, self.image_width);
            return Err(ConfigError::NotPoolable { h, w, times, div });
        }
        Ok(())
    }

    /// Layers, their sizes, tau, kernel, image and frame skip.
    fn validate_layers(&self) -> Result<(), ConfigError> {
        let layers = self.layers();
        if layers == 0 {
            return range("channels", "[]".into(), "needs at least one layer");
        }
        for (key, got) in [
            ("a_channels", self.a_channels.len()),
            ("gus", self.gus.len()),
            ("tau", self.tau.len()),
            ("xhat_bias", self.xhat_bias.len()),
            ("layer_loss_weights", self.layer_loss_weights.len()),
        ] {
            if got != layers {
                return Err(ConfigError::LayerCount { key, got, layers });
            }
        }
        if self.image_height < 1 || self.image_width < 1 {
            let v = format!("{}x{}", self.image_height, self.image_width);
            return range("image_height/image_width", v, "must be positive");
        }
        if !(1..=100).contains(&self.frame_skip) {
            let v = self.frame_skip.to_string();
            return range("frame_skip", v, "must be in 1..=100");
        }
        let sizes = self
            .channels
            .iter()
            .chain(&self.a_channels)
            .chain(&self.gus);
        if sizes.clone().any(|&c| c < 1) {
            return range(
                "channels/a_channels/gus",
                "0 or less".into(),
                "all must be >= 1",
            );
        }
        if self.a_channels[0] != 1 {
            let v = self.a_channels[0].to_string();
            return range(
                "a_channels[0]",
                v,
                "layer 0 is the grayscale image: must be 1",
            );
        }
        if let Some(t) = self.tau.iter().find(|t| !(**t >= 1.0 && t.is_finite())) {
            return range(
                "tau",
                t.to_string(),
                "must be finite and >= 1 (1 = no leak)",
            );
        }
        if self.kernel < 1 || self.kernel % 2 == 0 {
            return range("kernel", self.kernel.to_string(), "must be odd and >= 1");
        }
        Ok(())
    }

    /// The action's size, normalisation and MLP.
    fn validate_action(&self) -> Result<(), ConfigError> {
        if self.action_dim < 1 {
            return range("action_dim", self.action_dim.to_string(), "must be >= 1");
        }
        for (key, v) in [
            ("action_offset", &self.action_offset),
            ("action_scale", &self.action_scale),
        ] {
            if !v.is_empty() && v.len() != self.action_dim as usize {
                let got = format!("{} entries", v.len());
                return range(key, got, "must be empty or have action_dim entries");
            }
            if v.iter().any(|x| !x.is_finite()) {
                return range(key, format!("{v:?}"), "must be finite");
            }
        }
        if let Some(s) = self.action_scale.iter().find(|s| **s <= 0.0) {
            return range("action_scale", s.to_string(), "must be > 0");
        }
        if self.action_hidden < 1 {
            let v = self.action_hidden.to_string();
            return range("action_hidden", v, "must be >= 1");
        }
        Ok(())
    }

    /// The loss weights over layers and time.
    fn validate_loss(&self) -> Result<(), ConfigError> {
        let weights = self
            .layer_loss_weights
            .iter()
            .chain(&self.time_loss_weights);
        if let Some(w) = weights.clone().find(|w| !(**w >= 0.0 && w.is_finite())) {
            let key = "layer_loss_weights/time_loss_weights";
            return range(key, w.to_string(), "must be >= 0");
        }
        if self.time_loss_weights.is_empty() {
            return range("time_loss_weights", "[]".into(), "needs at least one entry");
        }
        if !self.layer_loss_weights.iter().any(|w| *w > 0.0) {
            return range(
                "layer_loss_weights",
                "all 0".into(),
                "nothing would be trained",
            );
        }
        Ok(())
    }

    /// Weight of the loss at (global) time step `t`.
    pub fn time_weight(&self, t: usize) -> f64 {
        let w = &self.time_loss_weights;
        w.get(t).or(w.last()).copied().unwrap_or(1.0)
    }

    /// Keys whose values differ from `other`, as `key: ours != theirs` lines (for load errors).
    pub fn differences(&self, other: &ModelConfig) -> Vec<String> {
        let (a, b) = (serde_json::to_value(self), serde_json::to_value(other));
        let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) = (a, b) else {
            return vec!["configuration could not be compared".into()];
        };
        a.iter()
            .filter(|(k, v)| b.get(*k) != Some(*v))
            .map(|(k, v)| {
                format!(
                    "{k}: {v} != {}",
                    b.get(k).unwrap_or(&serde_json::Value::Null)
                )
            })
            .collect()
    }
}

/// An out-of-range error for `key`.
fn range(key: &'static str, value: String, why: &'static str) -> Result<(), ConfigError> {
    Err(ConfigError::OutOfRange { key, value, why })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_paper_shaped() {
        let c = ModelConfig::default();
        c.validate().expect("default must validate");
        assert_eq!(
            (c.layers(), c.image_height, c.image_width, c.kernel),
            (3, 8, 12, 3)
        );
        assert_eq!(c.tau, vec![1.0, 1.3, 2.0]);
        assert_eq!(c.layer_size(2), (2, 3));
    }

    #[test]
    fn bad_configs_name_the_key() {
        let mut c = ModelConfig {
            tau: vec![1.0, 0.5, 2.0],
            ..Default::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("tau"));
        c.tau = vec![1.0, 2.0];
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("`tau` has 2")
        );
        c = ModelConfig {
            image_width: 10,
            ..Default::default()
        };
        assert!(matches!(c.validate(), Err(ConfigError::NotPoolable { .. })));
        let e = ModelConfig::from_toml("kernal = 3").unwrap_err();
        assert!(e.to_string().contains("kernal"), "{e}");
    }

    #[test]
    fn toml_round_trip_and_differences() {
        let c = ModelConfig {
            gus: vec![3, 2, 1],
            ..Default::default()
        };
        let text = toml::to_string(&c).unwrap();
        assert_eq!(ModelConfig::from_toml(&text).unwrap(), c);
        let d = c.differences(&ModelConfig::default());
        assert_eq!(d.len(), 1);
        assert!(d[0].starts_with("gus"), "{d:?}");
    }
}
