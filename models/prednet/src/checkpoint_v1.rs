//! Reading schema-1 checkpoints (and optimiser files): each generative unit had its own
//! convolution `layer{l}.gu{d}.conv.{weight,bias}` with weight `[4C, X + C, k, k]` over
//! `[E, up(R_{l+1}), h_d]`. Schema 2 stores a layer's units as one block,
//! `layer{l}.units.wx` `[G*4C, X, k, k]`, `wh` `[G*4C, C, k, k]` and `bias` `[G*4C]`, unit d in
//! rows d*4C..(d+1)*4C: the same numbers, regrouped, so a converted model computes exactly what
//! the old one did.

use std::collections::BTreeMap;

use tch::Tensor;

use crate::checkpoint::CheckpointError;

/// `(prefix + "layer{l}.", d, "weight" | "bias")` of a schema-1 unit tensor name. The prefix is
/// empty for weights and `m/` or `v/` for Adam moments.
fn unit_name(name: &str) -> Option<(String, usize, &str)> {
    let (head, leaf) = name.rsplit_once(".conv.")?;
    let (layer, gu) = head.rsplit_once('.')?;
    let d = gu.strip_prefix("gu")?.parse().ok()?;
    Some((format!("{layer}."), d, leaf))
}

/// Regroups every layer's unit tensors; every other tensor passes unchanged.
pub fn convert(
    tensors: BTreeMap<String, Tensor>,
) -> Result<BTreeMap<String, Tensor>, CheckpointError> {
    let bad = |why: String| CheckpointError::Tensors(vec![format!("schema-1 conversion: {why}")]);
    let mut out = BTreeMap::new();
    // layer prefix -> unit -> (weight, bias)
    let mut units: BTreeMap<String, BTreeMap<usize, (Option<Tensor>, Option<Tensor>)>> =
        BTreeMap::new();
    for (name, t) in tensors {
        match unit_name(&name) {
            Some((layer, d, "weight")) => {
                units.entry(layer).or_default().entry(d).or_default().0 = Some(t)
            }
            Some((layer, d, "bias")) => {
                units.entry(layer).or_default().entry(d).or_default().1 = Some(t)
            }
            _ => {
                out.insert(name, t);
            }
        }
    }
    for (layer, by_unit) in units {
        let (mut wx, mut wh, mut bias) = (Vec::new(), Vec::new(), Vec::new());
        for (i, (d, (w, b))) in by_unit.into_iter().enumerate() {
            if i != d {
                return Err(bad(format!("{layer}: unit {i} missing")));
            }
            let (w, b) = match (w, b) {
                (Some(w), Some(b)) => (w, b),
                _ => return Err(bad(format!("{layer}gu{d}: weight or bias missing"))),
            };
            let s = w.size();
            if s.len() != 4 || s[0] % 4 != 0 || s[1] <= s[0] / 4 || b.size() != [s[0]] {
                return Err(bad(format!(
                    "{layer}gu{d}: weight {s:?}, bias {:?}",
                    b.size()
                )));
            }
            let c = s[0] / 4;
            wx.push(w.narrow(1, 0, s[1] - c));
            wh.push(w.narrow(1, s[1] - c, c));
            bias.push(b);
        }
        let cat =
            |parts: &[Tensor]| Tensor::f_cat(parts, 0).map_err(|e| bad(format!("{layer}: {e}")));
        out.insert(format!("{layer}units.wx"), cat(&wx)?);
        out.insert(format!("{layer}units.wh"), cat(&wh)?);
        out.insert(format!("{layer}units.bias"), cat(&bias)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_recognised_with_and_without_a_moment_prefix() {
        assert_eq!(
            unit_name("layer1.gu0.conv.weight"),
            Some(("layer1.".into(), 0, "weight"))
        );
        assert_eq!(
            unit_name("m/layer2.gu1.conv.bias"),
            Some(("m/layer2.".into(), 1, "bias"))
        );
        assert_eq!(unit_name("layer1.xhat.weight"), None);
    }

    #[test]
    fn units_are_regrouped_row_block_by_row_block() {
        let mut t = BTreeMap::new();
        let (c, x, k) = (2, 3, 3);
        let w: Vec<Tensor> = (0..2)
            .map(|d| {
                Tensor::full(
                    [4 * c, x + c, k, k],
                    d as f64,
                    (tch::Kind::Float, tch::Device::Cpu),
                )
            })
            .collect();
        for d in 0..2 {
            t.insert(format!("layer0.gu{d}.conv.weight"), w[d].shallow_clone());
            t.insert(
                format!("layer0.gu{d}.conv.bias"),
                Tensor::full(
                    [4 * c],
                    d as f64 + 10.0,
                    (tch::Kind::Float, tch::Device::Cpu),
                ),
            );
        }
        t.insert(
            "layer0.xhat.weight".into(),
            Tensor::ones([1], (tch::Kind::Float, tch::Device::Cpu)),
        );
        let out = convert(t).unwrap();
        assert_eq!(out["layer0.units.wx"].size(), [2 * 4 * c, x, k, k]);
        assert_eq!(out["layer0.units.wh"].size(), [2 * 4 * c, c, k, k]);
        assert_eq!(out["layer0.units.bias"].double_value(&[4 * c]), 11.0);
        assert_eq!(out["layer0.units.wh"].double_value(&[4 * c, 0, 0, 0]), 1.0);
        assert!(out.contains_key("layer0.xhat.weight") && out.len() == 4);
        let mut broken = BTreeMap::new();
        broken.insert("layer0.gu1.conv.weight".to_string(), w[1].shallow_clone());
        assert!(
            convert(broken)
                .unwrap_err()
                .to_string()
                .contains("unit 0 missing")
        );
    }
}
