//! The ray-cast camera shows the line where geometry says it should be.
//!
//! The expected image is computed here independently of MuJoCo: from the documented camera
//! geometry (`car::CAMERA_*`) and pixel convention (row 0 = top = farthest, column 0 = car's
//! left), each pixel's ray is intersected with the floor and the hit point's distance to the
//! track polyline says line or floor.

use mtanet_scenes::car::*;
use mtanet_scenes::{
    IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH, SceneConfig, Sensors, Teacher, TeacherConfig, Track,
    World,
};

/// Pixel grey is dark (line) below this, light (floor) above.
const DARK: f32 = 0.5;
/// Hit points this close to the line's edge are not judged (the car sinks ~0.1 mm into the
/// floor, the line is 1 mm thick).
const EDGE_TOL_M: f64 = 0.002;

/// Where the ray of pixel (row, col) of a camera hits the line's top surface, in the world.
/// `cam_y`, `cam_yaw`: the camera's sideways offset and yaw in the car frame.
fn pixel_hit(pose: (f64, f64, f64), cam_y: f64, cam_yaw: f64, row: usize, col: usize) -> [f64; 2] {
    let ty = (CAMERA_FOVY_DEG.to_radians() / 2.0).tan();
    let tx = ty * IMAGE_WIDTH as f64 / IMAGE_HEIGHT as f64;
    let u = -1.0 + 2.0 * (col as f64 + 0.5) / IMAGE_WIDTH as f64; // -1 = left edge
    let v = 1.0 - 2.0 * (row as f64 + 0.5) / IMAGE_HEIGHT as f64; // +1 = top edge
    let (sp, cp) = CAMERA_PITCH_RAD.sin_cos();
    // Camera looking forward, pitched down: forward (cp, 0, -sp), up (sp, 0, cp), right (0,-1,0).
    let d = [cp + v * ty * sp, -u * tx, -sp + v * ty * cp];
    // Yaw the camera in the car, then the car in the world.
    let rot = |a: f64, p: [f64; 2]| {
        [
            a.cos() * p[0] - a.sin() * p[1],
            a.sin() * p[0] + a.cos() * p[1],
        ]
    };
    let dh = rot(pose.2 + cam_yaw, [d[0], d[1]]);
    let cam = rot(pose.2, [CAMERA_X_M, cam_y]);
    let t = (CAMERA_HEIGHT_M - 0.001) / -d[2];
    [pose.0 + cam[0] + t * dh[0], pose.1 + cam[1] + t * dh[1]]
}

/// Compares an image with the geometric expectation; returns how many pixels were judged
/// (dark, light).
fn check_image(
    track: &Track,
    img: &[f32; IMAGE_PIXELS],
    pose: (f64, f64, f64),
    cam_y: f64,
    cam_yaw: f64,
    what: &str,
) -> (usize, usize) {
    let hw = track.line_width_m() / 2.0;
    let (mut dark, mut light) = (0, 0);
    for row in 0..IMAGE_HEIGHT {
        for col in 0..IMAGE_WIDTH {
            let hit = pixel_hit(pose, cam_y, cam_yaw, row, col);
            let dist = track.project(hit).distance;
            let px = img[row * IMAGE_WIDTH + col];
            if dist < hw - EDGE_TOL_M {
                assert!(
                    px < DARK,
                    "{what}: pixel ({row},{col}) = {px}, expected line (hit {hit:?}, {dist:.4} m from it)"
                );
                dark += 1;
            } else if dist > hw + EDGE_TOL_M {
                assert!(
                    px > DARK,
                    "{what}: pixel ({row},{col}) = {px}, expected floor (hit {hit:?}, {dist:.4} m from line)"
                );
                light += 1;
            }
        }
    }
    (dark, light)
}

fn dark_columns(img: &[f32; IMAGE_PIXELS], row: usize) -> Vec<usize> {
    (0..IMAGE_WIDTH)
        .filter(|&c| img[row * IMAGE_WIDTH + c] < DARK)
        .collect()
}

fn mean_dark_column(img: &[f32; IMAGE_PIXELS]) -> f64 {
    let cols: Vec<usize> = (0..IMAGE_HEIGHT)
        .flat_map(|r| dark_columns(img, r))
        .collect();
    assert!(!cols.is_empty(), "no line in the image");
    cols.iter().sum::<usize>() as f64 / cols.len() as f64
}

fn oval_world(side_cameras: bool) -> World {
    World::new(&SceneConfig {
        side_cameras,
        ..SceneConfig::default()
    })
    .unwrap()
}

#[test]
fn line_centred_when_straddling_a_straight_and_moves_when_offset() {
    // The oval's first straight runs along y = 0 from x = -0.5 to 0.5, heading +x.
    let mut w = oval_world(false);
    w.set_pose(-0.2, 0.0, 0.0);
    let s = w.sense();
    for row in 0..IMAGE_HEIGHT {
        let cols = dark_columns(&s.image, row);
        assert!(
            cols.contains(&5) && cols.contains(&6),
            "row {row}: dark columns {cols:?}, expected the centre columns 5 and 6"
        );
        let mean = cols.iter().sum::<usize>() as f64 / cols.len() as f64;
        assert!(
            (mean - 5.5).abs() < 0.01,
            "row {row}: line not centred: {cols:?}"
        );
        assert!(cols.len() <= 4, "row {row}: line too wide: {cols:?}");
    }
    assert_eq!(s.line, [false, true, false]);
    assert!(s.truth.lateral_m.abs() < 1e-3);

    // Car moved 3 cm to its left (+y): the line is now to its right.
    w.set_pose(-0.2, 0.03, 0.0);
    let s = w.sense();
    let m = mean_dark_column(&s.image);
    assert!(m > 7.0, "line should be right of centre, mean column {m}");
    assert!(s.truth.lateral_m < -0.025, "{:?}", s.truth);
    // 2 cm: the right sensor (1.5 cm right of centre) is over the line, the middle one is not.
    w.set_pose(-0.2, 0.02, 0.0);
    assert_eq!(w.sense().line, [false, false, true]);
    w.set_pose(-0.2, -0.02, 0.0);
    assert_eq!(w.sense().line, [true, false, false]);

    // And 3 cm to its right: the line is to its left.
    w.set_pose(-0.2, -0.03, 0.0);
    let s = w.sense();
    let m = mean_dark_column(&s.image);
    assert!(m < 4.0, "line should be left of centre, mean column {m}");
    assert!(s.truth.lateral_m > 0.025, "{:?}", s.truth);

    // Turned 20 degrees left: the line ahead crosses to the right, more so far away (row 0).
    w.set_pose(-0.2, 0.0, 0.35);
    let s = w.sense();
    let far = dark_columns(&s.image, 0);
    let near = dark_columns(&s.image, IMAGE_HEIGHT - 1);
    let avg = |v: &[usize]| v.iter().sum::<usize>() as f64 / v.len().max(1) as f64;
    assert!(
        !far.is_empty() && avg(&far) > avg(&near),
        "far {far:?} near {near:?}"
    );
}

#[test]
fn images_match_geometry_along_every_track() {
    for name in ["oval", "bends", "s_loop", "square"] {
        let mut w = World::new(&SceneConfig {
            side_cameras: true,
            ..SceneConfig::default().with_track(mtanet_scenes::shipped_track(name))
        })
        .unwrap();
        let track = w.track().clone();
        let (mut dark, mut light) = (0, 0);
        let n = 40;
        for k in 0..n {
            // Poses along the track, offset and turned a little, deterministically varied.
            let s_along = track.length_m() * k as f64 / n as f64;
            let (p, h) = track.pose_at(s_along);
            let off = 0.02 * ((k % 5) as f64 - 2.0) / 2.0;
            let yaw = h + 0.15 * ((k % 3) as f64 - 1.0);
            let pose = (p[0] - off * h.sin(), p[1] + off * h.cos(), yaw);
            w.set_pose(pose.0, pose.1, pose.2);
            let s = w.sense();
            let what = format!("{name} pose {k} {pose:?}");
            let (d, l) = check_image(&track, &s.image, pose, 0.0, 0.0, &what);
            dark += d;
            light += l;
            let side = s.side_images.expect("side cameras on");
            check_image(
                &track,
                &side[0],
                pose,
                SIDE_CAMERA_Y_M,
                SIDE_CAMERA_YAW_RAD,
                &format!("{what} left cam"),
            );
            check_image(
                &track,
                &side[1],
                pose,
                -SIDE_CAMERA_Y_M,
                -SIDE_CAMERA_YAW_RAD,
                &format!("{what} right cam"),
            );
        }
        // Not vacuous: many line and floor pixels were judged.
        assert!(
            dark > 5 * n && light > 50 * n,
            "{name}: judged {dark} dark, {light} light"
        );
    }
}

#[test]
fn side_camera_sees_the_line_when_turned_towards_it() {
    // Car turned right by the side camera's yaw, placed so the left camera sits above the
    // line (y = 0): the left camera looks straight along it.
    let mut w = oval_world(true);
    let yaw = -SIDE_CAMERA_YAW_RAD;
    let cam_y = yaw.sin() * CAMERA_X_M + yaw.cos() * SIDE_CAMERA_Y_M;
    w.set_pose(-0.25, -cam_y, yaw);
    let s = w.sense();
    let [left, right] = s.side_images.unwrap();
    let m = mean_dark_column(&left);
    assert!((m - 5.5).abs() < 0.5, "left camera: line not centred ({m})");
    assert!(
        right.iter().all(|&p| p > DARK),
        "right camera looks away from the line"
    );
}

fn drive(w: &mut World, steps: usize, mut each: impl FnMut(&World, &Sensors)) {
    let mut t = Teacher::new(&TeacherConfig::default());
    let mut s = w.sense();
    for _ in 0..steps {
        let cmd = t.act(&s);
        w.step(cmd);
        s = w.sense();
        each(w, &s);
    }
}

#[test]
fn images_change_as_the_car_turns() {
    let mut w = oval_world(false);
    let track = w.track().clone();
    let mut distinct = std::collections::HashSet::new();
    let (mut bend_far, mut straight_far) = (vec![], vec![]);
    drive(&mut w, 1500, |_, s| {
        distinct.insert(s.image.map(f32::to_bits));
        // Curvature ahead of the car: heading change over the next 10 cm of line.
        let (_, h0) = track.pose_at(s.truth.track_s);
        let (_, h1) = track.pose_at(s.truth.track_s + 0.1);
        let turn = (h1 - h0 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        let far = dark_columns(&s.image, 0);
        if far.is_empty() {
            return;
        }
        let c = far.iter().sum::<usize>() as f64 / far.len() as f64;
        if turn > 0.2 {
            bend_far.push(c);
        } else if turn.abs() < 1e-3 {
            straight_far.push(c);
        }
    });
    assert!(
        distinct.len() > 50,
        "only {} distinct images in 30 s",
        distinct.len()
    );
    let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(bend_far.len() > 100 && straight_far.len() > 100);
    // The oval turns left: in bends the far end of the line sits left of where it sits on
    // straights.
    assert!(
        avg(&bend_far) + 1.0 < avg(&straight_far),
        "bend {:.2} vs straight {:.2}",
        avg(&bend_far),
        avg(&straight_far)
    );
}

#[test]
fn culling_far_geoms_does_not_change_images() {
    for name in ["oval", "s_loop"] {
        let cfg = SceneConfig {
            side_cameras: true,
            ..SceneConfig::default().with_track(mtanet_scenes::shipped_track(name))
        };
        let mut a = World::new(&cfg).unwrap();
        let mut b = World::new(&cfg).unwrap();
        b.set_culling(false);
        let mut t = Teacher::new(&TeacherConfig::default());
        let mut sa = a.sense();
        for k in 0..1500 {
            let cmd = t.act(&sa);
            a.step(cmd);
            b.step(cmd);
            sa = a.sense();
            let sb = b.sense();
            assert_eq!(
                sa.image.map(f32::to_bits),
                sb.image.map(f32::to_bits),
                "{name} step {k}"
            );
            assert_eq!(
                sa.side_images.unwrap()[0].map(f32::to_bits),
                sb.side_images.unwrap()[0].map(f32::to_bits)
            );
            assert_eq!(sa.line, sb.line, "{name} step {k}");
        }
    }
}

#[test]
fn supersampling_softens_edges_but_keeps_the_line_in_place() {
    let mut sharp = oval_world(false);
    let mut soft = World::new(&SceneConfig {
        camera_supersample: 3,
        ..SceneConfig::default()
    })
    .unwrap();
    let mut greys = 0;
    for (k, off) in [0.0, 0.007, -0.013, 0.021].iter().enumerate() {
        let yaw = 0.1 * k as f64 - 0.15;
        sharp.set_pose(-0.2, *off, yaw);
        soft.set_pose(-0.2, *off, yaw);
        let (a, b) = (sharp.sense().image, soft.sense().image);
        // Darkness-weighted mean column: where the line is.
        let centre = |img: &[f32; IMAGE_PIXELS]| {
            let (mut m, mut c) = (0.0, 0.0);
            for (i, p) in img.iter().enumerate() {
                let d = (0.85 - p).max(0.0) as f64;
                m += d;
                c += d * (i % IMAGE_WIDTH) as f64;
            }
            c / m
        };
        assert!(
            (centre(&a) - centre(&b)).abs() < 0.4,
            "offset {off}: {} vs {}",
            centre(&a),
            centre(&b)
        );
        let mean = |img: &[f32; IMAGE_PIXELS]| img.iter().sum::<f32>() / IMAGE_PIXELS as f32;
        assert!((mean(&a) - mean(&b)).abs() < 0.05);
        greys += b.iter().filter(|&&p| p > 0.15 && p < 0.8).count();
    }
    assert!(
        greys > 10,
        "supersampled edges should have intermediate greys, found {greys}"
    );
}
