//! Drives the teacher on a track and writes what the camera saw as a PNG contact sheet, one
//! 8x12 frame (scaled up) every `every` control steps. For eyeballing the world:
//!
//! `cargo run --release -p mtanet-scenes --example snapshot -- oval out.png [seconds] [every]`

use std::fs::File;
use std::io::BufWriter;

use mtanet_scenes::{
    IMAGE_HEIGHT, IMAGE_WIDTH, SceneConfig, Teacher, TeacherConfig, World, shipped_track,
};

const SCALE: usize = 6;
const COLS: usize = 10;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let track = args.get(1).map_or("oval", String::as_str);
    let out = args.get(2).map_or("snapshot.png", String::as_str);
    let seconds: f64 = args.get(3).map_or(Ok(20.0), |s| s.parse())?;
    let every: usize = args.get(4).map_or(Ok(25), |s| s.parse())?;

    let mut world = World::new(&SceneConfig::default().with_track(shipped_track(track)))?;
    let mut teacher = Teacher::new(&TeacherConfig::default());
    let mut s = world.sense();
    let mut frames = vec![s.image];
    let steps = (seconds / mtanet_scenes::CONTROL_PERIOD_S) as usize;
    for k in 1..=steps {
        let cmd = teacher.act(&s);
        world.step(cmd);
        s = world.sense();
        if k % every == 0 {
            frames.push(s.image);
        }
    }
    println!(
        "{} frames, laps {}, truth {:?}",
        frames.len(),
        s.truth.laps,
        s.truth
    );

    let (fw, fh) = (IMAGE_WIDTH * SCALE + 2, IMAGE_HEIGHT * SCALE + 2);
    let rows = frames.len().div_ceil(COLS);
    let (w, h) = (COLS * fw, rows * fh);
    let mut pix = vec![64u8; w * h];
    for (i, f) in frames.iter().enumerate() {
        let (ox, oy) = ((i % COLS) * fw + 1, (i / COLS) * fh + 1);
        for y in 0..IMAGE_HEIGHT * SCALE {
            for x in 0..IMAGE_WIDTH * SCALE {
                let v = f[(y / SCALE) * IMAGE_WIDTH + x / SCALE];
                pix[(oy + y) * w + ox + x] = (v.clamp(0.0, 1.0) * 255.0) as u8;
            }
        }
    }
    let mut enc = png::Encoder::new(BufWriter::new(File::create(out)?), w as u32, h as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(&pix)?;
    println!("wrote {out}");
    Ok(())
}
