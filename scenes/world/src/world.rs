//! The simulated world: the compiled scene, its state, and the sensors read from it.

use mujoco_rs::prelude::*;

use crate::camera::{RayCamera, luminance};
use crate::car::{self, names};
use crate::config::{SceneConfig, SceneError};
use crate::cull::LineCulling;
use crate::mjcf::{self, FLOOR_GROUP, LINE_GROUP, MjcfOptions};
use crate::truth::{self, GroundTruth, LapCounter};
use crate::{IMAGE_PIXELS, Sensors};
use mtanet_track::Track;

/// Geom groups the cameras see (floor and line) and the line sensors react to (line only).
fn group_mask(groups: &[u8]) -> [u8; 6] {
    let mut m = [0u8; 6];
    for &g in groups {
        m[g as usize] = 1;
    }
    m
}

/// Model indices looked up once by name.
#[derive(Debug, Clone)]
struct Ids {
    free_qpos: usize,
    free_qvel: usize,
    actuators: [usize; 2],
    wheel_sensors: [usize; 2],
    line_sites: [usize; 3],
}

/// Id of a named model object; a miss is a generator bug, reported rather than panicking.
fn find(
    m: &MjModel,
    kind: MjtObjBase,
    label: &'static str,
    name: &str,
) -> Result<usize, SceneError> {
    m.name_to_id(kind, name)
        .ok_or_else(|| SceneError::MissingObject {
            kind: label,
            name: name.to_string(),
        })
}

impl Ids {
    fn lookup(m: &MjModel) -> Result<Ids, SceneError> {
        type O = MjtObjBase;
        let free = find(m, O::mjOBJ_JOINT, "joint", names::BODY)?;
        let act = |k: usize| find(m, O::mjOBJ_ACTUATOR, "actuator", names::WHEEL_JOINTS[k]);
        let sens = |k: usize| -> Result<usize, SceneError> {
            let s = find(m, O::mjOBJ_SENSOR, "sensor", names::WHEEL_SENSORS[k])?;
            Ok(m.sensor_adr()[s] as usize)
        };
        let site = |k: usize| find(m, O::mjOBJ_SITE, "site", names::LINE_SITES[k]);
        Ok(Ids {
            free_qpos: m.jnt_qposadr()[free] as usize,
            free_qvel: m.jnt_dofadr()[free] as usize,
            actuators: [act(0)?, act(1)?],
            wheel_sensors: [sens(0)?, sens(1)?],
            line_sites: [site(0)?, site(1)?, site(2)?],
        })
    }
}

/// Everything [`World::step`] and [`World::sense`] depend on, to put the world back exactly where
/// it was: MuJoCo's integration state plus the world's own bookkeeping. The oracle planner and
/// the counterfactual probe roll candidate futures out from one of these.
#[derive(Debug, Clone)]
pub struct WorldState {
    physics: Box<[f64]>,
    cmd: [f64; 2],
    laps: LapCounter,
}

/// What MuJoCo's state holds for a snapshot: everything integration depends on.
const STATE_SPEC: u32 = MjtState::mjSTATE_INTEGRATION as u32;

/// A line-tracer car on a track. Not thread-safe to share, but can move between threads.
pub struct World {
    cfg: SceneConfig,
    track: Track,
    mjcf: String,
    data: MjData<Box<MjModel>>,
    ids: Ids,
    substeps: u32,
    cmd: [f64; 2],
    rejected: u64,
    laps: LapCounter,
    camera: RayCamera,
    side_cameras: Option<[RayCamera; 2]>,
    geom_grey: Vec<f32>,
    culling: LineCulling,
    camera_groups: [u8; 6],
    line_groups: [u8; 6],
    /// Set by `mj_step_bare`: kinematics and sensors lag the state until the next `forward`.
    stale: bool,
}

impl World {
    /// Loads the track, generates the MJCF, compiles it with MuJoCo and places the car at the
    /// start (sensor bar on the line at `start_s_m`, heading along it).
    pub fn new(cfg: &SceneConfig) -> Result<World, SceneError> {
        let substeps = cfg.validate()?;
        let track = Track::load(&cfg.track)?;
        let mjcf = mjcf::scene(
            &track,
            &MjcfOptions {
                timestep_s: cfg.physics_timestep_s,
                max_wheel_speed: cfg.max_wheel_speed,
                start_s_m: cfg.start_s_m,
            },
        );
        let model = MjModel::from_xml_string(&mjcf).map_err(|e| SceneError::Compile {
            track: cfg.track.clone(),
            message: e.to_string(),
        })?;
        let data = MjData::try_new(Box::new(model)).map_err(|e| SceneError::Compile {
            track: cfg.track.clone(),
            message: e.to_string(),
        })?;
        let m = data.model();
        let ids = Ids::lookup(m)?;
        let cam = |name: &str| -> Result<RayCamera, SceneError> {
            let c = find(m, MjtObjBase::mjOBJ_CAMERA, "camera", name)?;
            let ss = cfg.camera_supersample as usize;
            Ok(RayCamera::new(c, m.cam_fovy()[c], ss))
        };
        let camera = cam(names::CAMERA_MID)?;
        let side_cameras = if cfg.side_cameras {
            Some([cam(names::CAMERAS_SIDE[0])?, cam(names::CAMERAS_SIDE[1])?])
        } else {
            None
        };
        let geom_grey = m.geom_rgba().iter().map(|&c| luminance(c)).collect();
        let culling = LineCulling::new(m);
        let laps = LapCounter::new(track.length_m(), 0.0);
        let mut world = World {
            cfg: cfg.clone(),
            track,
            mjcf,
            data,
            ids,
            substeps,
            cmd: [0.0; 2],
            rejected: 0,
            laps,
            camera,
            side_cameras,
            geom_grey,
            culling,
            camera_groups: group_mask(&[FLOOR_GROUP, LINE_GROUP]),
            line_groups: group_mask(&[LINE_GROUP]),
            stale: false,
        };
        world.reset();
        Ok(world)
    }

    /// The generated MJCF.
    pub fn mjcf(&self) -> &str {
        &self.mjcf
    }

    pub fn track(&self) -> &Track {
        &self.track
    }

    pub fn config(&self) -> &SceneConfig {
        &self.cfg
    }

    /// Physics steps per control step.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// The wheel command in force (the last accepted one, after clamping), rad/s.
    pub fn command(&self) -> [f64; 2] {
        self.cmd
    }

    /// Applies the wheel command [left, right] in rad/s for one control period (several physics
    /// steps). A non-finite command is rejected (counted) and the last good command is kept;
    /// returns whether it was accepted. Accepted commands are clamped to `max_wheel_speed`.
    pub fn step(&mut self, wheel_cmd: [f32; 2]) -> bool {
        let accepted = wheel_cmd.iter().all(|v| v.is_finite());
        if accepted {
            let lim = self.cfg.max_wheel_speed;
            self.cmd = wheel_cmd.map(|v| (v as f64).clamp(-lim, lim));
        } else {
            self.rejected += 1;
            tracing::debug!(?wheel_cmd, "rejected a non-finite wheel command");
        }
        self.refresh();
        let [a, b] = self.ids.actuators;
        let ctrl = self.data.ctrl_mut();
        ctrl[a] = self.cmd[0];
        ctrl[b] = self.cmd[1];
        // step2 then step1: the state advances, then kinematics and sensors are brought up to
        // date for it, so `sense` reads the present and not the state one physics step ago.
        for _ in 0..self.substeps {
            self.data.step2();
            self.data.step1();
        }
        let (s, _) = self.bar_on_track();
        self.laps.update(s);
        accepted
    }

    /// One bare MuJoCo step (`mj_step`, one physics time step) with the command in force: no
    /// sensors, no bookkeeping. For benchmarks; lap counting misses what happens here.
    pub fn mj_step_bare(&mut self) {
        self.data.step();
        self.stale = true;
    }

    /// Brings kinematics and sensor data up to date after bare steps.
    fn refresh(&mut self) {
        if self.stale {
            self.data.forward();
            self.stale = false;
        }
    }

    /// All sensors at the current state.
    pub fn sense(&mut self) -> Sensors {
        self.refresh();
        let (x, y, _) = self.pose();
        self.culling.update(&mut self.data, [x, y]);
        let mut image = [0.0; IMAGE_PIXELS];
        self.camera.render(
            &mut self.data,
            &self.camera_groups,
            &self.geom_grey,
            &mut image,
        );
        let side_images = self.side_cameras.as_mut().map(|cams| {
            let mut imgs = [[0.0; IMAGE_PIXELS]; 2];
            for (cam, img) in cams.iter_mut().zip(imgs.iter_mut()) {
                cam.render(&mut self.data, &self.camera_groups, &self.geom_grey, img);
            }
            imgs
        });
        let line = self.line_sensors();
        let sd = self.data.sensordata();
        let wheel_velocity = self.ids.wheel_sensors.map(|adr| sd[adr] as f32);
        Sensors {
            image,
            side_images,
            line,
            wheel_velocity,
            truth: self.truth(),
        }
    }

    /// Line sensors: a short ray straight down from each sensor site; on when it hits the line.
    fn line_sensors(&mut self) -> [bool; 3] {
        let mut on = [false; 3];
        for (k, &site) in self.ids.line_sites.iter().enumerate() {
            let pos = self.data.site_xpos()[site];
            let (hit, dist) = self.data.ray(
                &pos,
                &[0.0, 0.0, -1.0],
                Some(&self.line_groups),
                true,
                None,
                None,
            );
            // The line's top is 1 cm below the site; anything farther is not under the sensor.
            on[k] = hit.is_some() && (0.0..2.0 * car::SENSOR_HEIGHT_M).contains(&dist);
        }
        on
    }

    /// Turns the culling of far line geoms off or on (default on). Images are the same either
    /// way; this exists to test that and to measure what culling saves.
    pub fn set_culling(&mut self, enabled: bool) {
        self.culling.set_enabled(&mut self.data, enabled);
    }

    /// Position and heading of the car origin.
    fn pose(&self) -> (f64, f64, f64) {
        let q = &self.data.qpos()[self.ids.free_qpos..self.ids.free_qpos + 7];
        let (w, x, y, z) = (q[3], q[4], q[5], q[6]);
        let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
        (q[0], q[1], yaw)
    }

    /// Track arc length and signed lateral offset at the sensor-bar centre (the middle site).
    fn bar_on_track(&self) -> (f64, f64) {
        let bar = self.data.site_xpos()[self.ids.line_sites[1]];
        let (_, _, yaw) = self.pose();
        truth::lateral(&self.track, [bar[0], bar[1]], yaw)
    }

    /// Ground truth at the current state.
    pub fn truth(&self) -> GroundTruth {
        let (x, y, yaw) = self.pose();
        let (track_s, lateral_m) = self.bar_on_track();
        GroundTruth {
            x,
            y,
            yaw,
            track_s,
            lateral_m,
            laps: self.laps.laps(),
            on_line: lateral_m.abs() < self.track.line_width_m() / 2.0,
        }
    }

    /// Net distance driven along the track since the start/reset (negative when reversing),
    /// metres; `truth().laps` is its whole number of track lengths, high-water marked.
    pub fn progress_m(&self) -> f64 {
        self.laps.progress()
    }

    /// Simulated time since the start/reset, seconds.
    pub fn time_s(&self) -> f64 {
        self.data.time()
    }

    /// Non-finite commands rejected since the world was built (not cleared by `reset`: it is a
    /// health counter of whoever drives the world).
    pub fn rejected_commands(&self) -> u64 {
        self.rejected
    }

    /// Puts the car origin (axle midpoint) at (x, y) with heading `yaw`, at rest on the floor.
    /// Keeps the time, the command and the lap count (the jump itself is not counted as
    /// progress). Returns false, leaving the car where it was, if a value is not finite.
    pub fn set_pose(&mut self, x: f64, y: f64, yaw: f64) -> bool {
        if !(x.is_finite() && y.is_finite() && yaw.is_finite()) {
            tracing::warn!(x, y, yaw, "set_pose ignored: non-finite pose");
            return false;
        }
        let (qa, va) = (self.ids.free_qpos, self.ids.free_qvel);
        let (s, c) = (yaw / 2.0).sin_cos();
        let qpos = self.data.qpos_mut();
        qpos[qa..qa + 7].copy_from_slice(&[x, y, car::WHEEL_RADIUS_M, c, 0.0, 0.0, s]);
        // The free joint's 6 dofs and the wheels: the car is placed at rest.
        self.data.qvel_mut()[va..].fill(0.0);
        self.data.forward();
        self.stale = false;
        let (s, _) = self.bar_on_track();
        self.laps.reanchor(s);
        true
    }

    /// Puts the car at rest with its sensor bar at arc length `s_m` of the track, `lateral_m`
    /// off the line (sign as `GroundTruth::lateral_m`) and heading along the line turned by
    /// `yaw_offset` radians (left positive). Same bookkeeping and result as `set_pose`.
    pub fn place_on_track(&mut self, s_m: f64, lateral_m: f64, yaw_offset: f64) -> bool {
        if !(s_m.is_finite() && lateral_m.is_finite() && yaw_offset.is_finite()) {
            tracing::warn!(
                s_m,
                lateral_m,
                yaw_offset,
                "place_on_track ignored: non-finite"
            );
            return false;
        }
        let (p, yaw) = mjcf::pose_on_track(&self.track, s_m, lateral_m, yaw_offset);
        self.set_pose(p[0], p[1], yaw)
    }

    /// The whole state, for [`World::restore`].
    pub fn snapshot(&mut self) -> WorldState {
        self.refresh();
        WorldState {
            physics: self.data.state(STATE_SPEC),
            cmd: self.cmd,
            laps: self.laps.clone(),
        }
    }

    /// Puts the world back to a snapshot taken from this world (or one built from the same
    /// scene): the same commands then give the same sensors, bit for bit.
    pub fn restore(&mut self, state: &WorldState) {
        self.data
            .set_state(&state.physics, STATE_SPEC)
            .expect("a snapshot of this scene has the state size of this scene");
        self.cmd = state.cmd;
        self.laps = state.laps.clone();
        self.data.forward();
        self.stale = false;
    }

    /// Back to the start pose at rest, time 0, command 0, lap count 0.
    pub fn reset(&mut self) {
        // qpos0 holds the start pose written into the MJCF.
        self.data.reset();
        self.cmd = [0.0; 2];
        self.data.forward();
        self.stale = false;
        let (s, _) = self.bar_on_track();
        self.laps = LapCounter::new(self.track.length_m(), s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The culling radius must cover everything any camera can see on the floor, with margin
    /// for the car rocking.
    #[test]
    fn cull_radius_covers_camera_footprint() {
        // Supersampled: the outermost sub-rays reach nearly to the image corners.
        let cfg = SceneConfig {
            side_cameras: true,
            camera_supersample: 4,
            ..SceneConfig::default()
        };
        let mut w = World::new(&cfg).unwrap();
        let (x, y, _) = w.pose();
        let mut cams = vec![w.camera.clone()];
        cams.extend(w.side_cameras.clone().unwrap());
        let mut far: f64 = 0.0;
        for cam in &mut cams {
            let p = cam.update_rays(&w.data);
            for d in cam.rays() {
                assert!(d[2] < 0.0, "a pixel ray points above the horizon: {d:?}");
                let t = -p[2] / d[2];
                let (hx, hy) = (p[0] + t * d[0], p[1] + t * d[1]);
                far = far.max((hx - x).hypot(hy - y));
            }
        }
        assert!(
            far * 1.3 < crate::cull::CULL_RADIUS_M,
            "cameras see {far:.3} m from the car, culling radius {} m",
            crate::cull::CULL_RADIUS_M
        );
        w.reset();
    }
}
