//! Hides line geoms far from the car from the rays.
//!
//! `mj_multiRay` tests every geom of the selected groups against every ray, so an 8x12 image of
//! a track with 270 line geoms cost ~300 us, 4x the physics. Only the few geoms within sight of
//! the cameras can be hit, so the others are moved into a geom group no ray selects. Geom groups
//! only filter rays and rendering; physics never reads them.

use mujoco_rs::prelude::*;

use crate::mjcf::LINE_GROUP;

/// Geom group for line geoms out of sight: no camera or sensor selects it.
pub const HIDDEN_GROUP: i32 = 5;
/// Line geoms whose bounding circle comes within this distance of the car origin stay visible.
/// The cameras see the floor at most 0.233 m from the origin (a unit test in `world.rs` checks
/// this radius has 30% margin); the margin covers a car rocking on its caster.
/// `tests/camera.rs` compares culled against unculled images while driving.
pub const CULL_RADIUS_M: f64 = 0.35;

#[derive(Debug, Clone)]
pub(crate) struct LineCulling {
    geoms: Vec<usize>,
    centres: Vec<[f64; 2]>,
    radii: Vec<f64>,
    visible: Vec<bool>,
    enabled: bool,
}

impl LineCulling {
    /// Collects the line geoms (those compiled into `LINE_GROUP`). All start visible.
    pub fn new(model: &MjModel) -> Self {
        let mut c = LineCulling {
            geoms: Vec::new(),
            centres: Vec::new(),
            radii: Vec::new(),
            visible: Vec::new(),
            enabled: true,
        };
        let groups = model.geom_group();
        let pos = model.geom_pos();
        let rbound = model.geom_rbound();
        for g in 0..groups.len() {
            if groups[g] == LINE_GROUP as i32 {
                c.geoms.push(g);
                c.centres.push([pos[g][0], pos[g][1]]);
                c.radii.push(rbound[g]);
                c.visible.push(true);
            }
        }
        c
    }

    /// Switch culling off (every line geom visible) or on; for tests and comparisons.
    pub fn set_enabled<M: mujoco_rs::wrappers::mj_model::traits::ModelTypeMut>(
        &mut self,
        data: &mut MjData<M>,
        enabled: bool,
    ) {
        self.enabled = enabled;
        if !enabled {
            self.apply(data, |_| true);
        }
    }

    /// Makes the geoms near `car` visible and the rest hidden.
    pub fn update<M: mujoco_rs::wrappers::mj_model::traits::ModelTypeMut>(
        &mut self,
        data: &mut MjData<M>,
        car: [f64; 2],
    ) {
        if !self.enabled {
            return;
        }
        let centres = std::mem::take(&mut self.centres);
        let radii = std::mem::take(&mut self.radii);
        self.apply(data, |k| {
            let (c, r) = (centres[k], radii[k] + CULL_RADIUS_M);
            let (dx, dy) = (c[0] - car[0], c[1] - car[1]);
            dx * dx + dy * dy < r * r
        });
        self.centres = centres;
        self.radii = radii;
    }

    fn apply<M: mujoco_rs::wrappers::mj_model::traits::ModelTypeMut>(
        &mut self,
        data: &mut MjData<M>,
        want: impl Fn(usize) -> bool,
    ) {
        for k in 0..self.geoms.len() {
            let v = want(k);
            if v != self.visible[k] {
                self.visible[k] = v;
                // SAFETY: only one `geom_group` entry is written, with a valid group (0..6);
                // no size, index or address table of the model changes, so the data stays
                // consistent with it.
                let model = unsafe { data.model_mut() };
                model.geom_group_mut()[self.geoms[k]] =
                    if v { LINE_GROUP as i32 } else { HIDDEN_GROUP };
            }
        }
    }
}
