//! The line-tracer car: dimensions and its MJCF body. Modelled on V-REP's LineTracer (differential
//! drive, a sensor bar of three downward line sensors at the front, small cameras looking
//! ahead/down), scaled to a 2.5 cm line.
//!
//! Car frame: x forward, y left, z up; the origin is the midpoint between the wheel centres.

use std::fmt::Write;

/// Wheel radius (m).
pub const WHEEL_RADIUS_M: f64 = 0.027;
/// Half the distance between the wheel centres (m).
pub const AXLE_HALF_M: f64 = 0.05;
/// How far ahead of the axle the sensor bar sits (m). Ground truth measures the lateral error
/// here, where the sensors are, not at the axle.
pub const SENSOR_X_M: f64 = 0.085;
/// Lateral offset of the side line sensors (m). A little more than half the line width, so with
/// the car centred only the middle sensor sees the line.
pub const SENSOR_SPACING_M: f64 = 0.015;
/// Height of the line-sensor ray origins above the floor (m).
pub const SENSOR_HEIGHT_M: f64 = 0.01;
/// Middle camera: ahead of the axle, above the floor, pitched down, vertical field of view.
pub const CAMERA_X_M: f64 = 0.09;
pub const CAMERA_HEIGHT_M: f64 = 0.077;
pub const CAMERA_PITCH_RAD: f64 = 50.0 * std::f64::consts::PI / 180.0;
pub const CAMERA_FOVY_DEG: f64 = 40.0;
/// Side cameras: yawed outwards by this much and moved sideways by `SIDE_CAMERA_Y_M`.
pub const SIDE_CAMERA_YAW_RAD: f64 = 35.0 * std::f64::consts::PI / 180.0;
pub const SIDE_CAMERA_Y_M: f64 = 0.03;

/// Reflected inertia of motor + gearbox at the wheel (kg m^2). Without it the bare wheel (1e-5)
/// is so light that a torque at the actuator's force limit, which MuJoCo integrates explicitly,
/// overshoots the commanded speed several-fold within one 5 ms step.
pub const WHEEL_ARMATURE: f64 = 5e-4;
/// Velocity servo gain (N m per rad/s) and torque limit (N m): time constant armature/kv = 25 ms,
/// about one control period, like a small geared motor; the limit stays near the tyre grip
/// (~0.03 N m) so the wheels do not spin.
pub const WHEEL_KV: f64 = 0.02;
pub const WHEEL_MAX_TORQUE: f64 = 0.04;

/// Geom group of the car's own geoms: the cameras and line sensors leave it out so the car never
/// sees itself.
pub const CAR_GROUP: u8 = 2;

/// Names shared between the MJCF and the code that looks them up.
pub mod names {
    pub const BODY: &str = "car";
    pub const WHEEL_JOINTS: [&str; 2] = ["wheel_left", "wheel_right"];
    pub const WHEEL_SENSORS: [&str; 2] = ["wheel_left_vel", "wheel_right_vel"];
    pub const LINE_SITES: [&str; 3] = ["line_left", "line_middle", "line_right"];
    pub const CAMERA_MID: &str = "cam_middle";
    pub const CAMERAS_SIDE: [&str; 2] = ["cam_left", "cam_right"];
}

/// Camera `xyaxes` for a camera pitched down by `pitch` and yawed left by `yaw` (car frame).
/// MuJoCo cameras look along their -z with +y up in the image; image x = car right when yaw = 0.
fn camera_xyaxes(pitch: f64, yaw: f64) -> [f64; 6] {
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    // Unrotated: x_cam = (0,-1,0), y_cam = (sin p, 0, cos p); then rotate about z by yaw.
    let rot = |v: [f64; 3]| [cy * v[0] - sy * v[1], sy * v[0] + cy * v[1], v[2]];
    let x = rot([0.0, -1.0, 0.0]);
    let y = rot([sp, 0.0, cp]);
    [x[0], x[1], x[2], y[0], y[1], y[2]]
}

/// Writes the car body (free joint, chassis, wheels, caster, sensor sites, cameras) at `pos`
/// with heading `yaw`; `pos` is the axle midpoint on the floor.
pub fn write_body(out: &mut String, pos: [f64; 2], yaw: f64) {
    let r = WHEEL_RADIUS_M;
    let caster_r = 0.01;
    // The body origin is at axle height so the wheels rest on the floor.
    let _ = writeln!(
        out,
        r#"    <body name="{body}" pos="{x:.6} {y:.6} {r}" euler="0 0 {yaw:.6}">
      <freejoint name="{body}"/>
      <geom name="chassis" type="box" size="0.055 0.035 0.008" pos="0.025 0 0.005" mass="0.2" group="{g}" rgba="0.2 0.4 0.8 1"/>
      <geom name="sensor_bar" type="box" size="0.006 0.025 0.003" pos="{sx} 0 {bar_z:.4}" mass="0.005" group="{g}" rgba="0.3 0.3 0.3 1"/>
      <geom name="caster" type="sphere" size="{caster_r}" pos="0.065 0 {caster_z:.4}" mass="0.005" condim="1" priority="1" group="{g}" rgba="0.6 0.6 0.6 1"/>"#,
        body = names::BODY,
        x = pos[0],
        y = pos[1],
        g = CAR_GROUP,
        sx = SENSOR_X_M,
        bar_z = SENSOR_HEIGHT_M + 0.004 - r,
        caster_z = caster_r - r,
    );
    for (k, side) in [1.0, -1.0].iter().enumerate() {
        let _ = writeln!(
            out,
            r#"      <body name="{j}" pos="0 {y} 0">
        <joint name="{j}" type="hinge" axis="0 1 0" armature="{arm}" damping="0.0002"/>
        <geom type="cylinder" size="{r} 0.006" zaxis="0 1 0" mass="0.03" friction="1.2 0.01 0.001" group="{g}" rgba="0.1 0.1 0.1 1"/>
      </body>"#,
            j = names::WHEEL_JOINTS[k],
            y = side * AXLE_HALF_M,
            arm = WHEEL_ARMATURE,
            g = CAR_GROUP,
        );
    }
    for (k, lat) in [SENSOR_SPACING_M, 0.0, -SENSOR_SPACING_M]
        .iter()
        .enumerate()
    {
        let _ = writeln!(
            out,
            r#"      <site name="{n}" pos="{sx} {lat} {z:.4}" size="0.003" group="{g}"/>"#,
            n = names::LINE_SITES[k],
            sx = SENSOR_X_M,
            z = SENSOR_HEIGHT_M - r,
            g = CAR_GROUP,
        );
    }
    let cams = [
        (names::CAMERA_MID, 0.0, 0.0),
        (names::CAMERAS_SIDE[0], SIDE_CAMERA_Y_M, SIDE_CAMERA_YAW_RAD),
        (
            names::CAMERAS_SIDE[1],
            -SIDE_CAMERA_Y_M,
            -SIDE_CAMERA_YAW_RAD,
        ),
    ];
    for (name, y, yaw) in cams {
        let a = camera_xyaxes(CAMERA_PITCH_RAD, yaw);
        let _ = writeln!(
            out,
            r#"      <camera name="{name}" pos="{cx} {y} {cz:.4}" xyaxes="{:.6} {:.6} {:.6} {:.6} {:.6} {:.6}" fovy="{CAMERA_FOVY_DEG}"/>"#,
            a[0],
            a[1],
            a[2],
            a[3],
            a[4],
            a[5],
            cx = CAMERA_X_M,
            cz = CAMERA_HEIGHT_M - r,
        );
    }
    out.push_str("    </body>\n");
}

/// Actuators and sensors of the car (top-level MJCF sections).
pub fn write_actuators_and_sensors(out: &mut String, max_wheel_speed: f64) {
    out.push_str("  <actuator>\n");
    for j in names::WHEEL_JOINTS {
        // A velocity servo stands in for the motor + speed controller of a real line tracer.
        let _ = writeln!(
            out,
            r#"    <velocity name="{j}" joint="{j}" kv="{WHEEL_KV}" ctrlrange="{lo} {hi}" forcerange="-{WHEEL_MAX_TORQUE} {WHEEL_MAX_TORQUE}"/>"#,
            lo = -max_wheel_speed,
            hi = max_wheel_speed,
        );
    }
    out.push_str("  </actuator>\n  <sensor>\n");
    for (j, s) in names::WHEEL_JOINTS.iter().zip(names::WHEEL_SENSORS) {
        let _ = writeln!(out, r#"    <jointvel name="{s}" joint="{j}"/>"#);
    }
    out.push_str("  </sensor>\n");
}
