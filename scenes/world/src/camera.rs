//! The 8x12 grayscale camera, by ray casting: one ray per pixel through the pixel centre, grey
//! from the colour of the geom hit. The paper's V-REP vision sensor was this small, and rays cost
//! 30-80 us an image where a headless OpenGL render costs 0.5-1 ms (docs/measurements.md).

use mujoco_rs::prelude::*;

use crate::{IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH};

/// Grey of a pixel whose ray hits nothing within `MAX_RAY_M` (only possible above the horizon).
pub const BACKGROUND_GREY: f32 = 0.5;
/// Rays longer than this count as "nothing hit"; far beyond what a camera pitched down can see.
const MAX_RAY_M: f64 = 5.0;

/// Grey level of an RGBA colour: Rec. 709 luminance, so a colour scene would still read sensibly.
pub fn luminance(rgba: [f32; 4]) -> f32 {
    (0.2126 * rgba[0] + 0.7152 * rgba[1] + 0.0722 * rgba[2]).clamp(0.0, 1.0)
}

/// A camera of the model rendered by rays. Pixel directions are fixed in the camera frame and
/// rotated by the camera's world orientation each frame.
#[derive(Debug, Clone)]
pub struct RayCamera {
    cam_id: usize,
    /// Rays per pixel = supersample^2, on a regular sub-grid; 1 = through the pixel centre.
    supersample: usize,
    dirs_cam: Vec<[f64; 3]>,
    dirs_world: Vec<[f64; 3]>,
}

impl RayCamera {
    /// `fovy_deg` is the vertical field of view; pixels are square, so the horizontal one
    /// follows from the 12:8 aspect. `supersample` n casts n x n rays per pixel and averages
    /// them (edges of the line then get intermediate greys); 1 casts one ray through the centre.
    pub fn new(cam_id: usize, fovy_deg: f64, supersample: usize) -> Self {
        let n = supersample.max(1);
        let ty = (fovy_deg.to_radians() / 2.0).tan();
        let tx = ty * IMAGE_WIDTH as f64 / IMAGE_HEIGHT as f64;
        let mut dirs_cam = Vec::with_capacity(IMAGE_PIXELS * n * n);
        // Offsets of the sub-rays inside a pixel, in pixel units: (k + 0.5) / n.
        let sub = |k: usize| (k as f64 + 0.5) / n as f64;
        for row in 0..IMAGE_HEIGHT {
            for col in 0..IMAGE_WIDTH {
                for i in 0..n {
                    // Row 0 is the top of the image (+y in the camera frame): farthest ahead.
                    let v = 1.0 - 2.0 * (row as f64 + sub(i)) / IMAGE_HEIGHT as f64;
                    for j in 0..n {
                        // Column 0 is the image's left (-x in the camera frame): the car's left.
                        let u = -1.0 + 2.0 * (col as f64 + sub(j)) / IMAGE_WIDTH as f64;
                        dirs_cam.push([u * tx, v * ty, -1.0]);
                    }
                }
            }
        }
        RayCamera {
            cam_id,
            supersample: n,
            dirs_world: dirs_cam.clone(),
            dirs_cam,
        }
    }

    /// Rotates the pixel rays into the world; returns the camera position.
    pub(crate) fn update_rays<M: mujoco_rs::wrappers::mj_model::traits::ModelType>(
        &mut self,
        data: &MjData<M>,
    ) -> [f64; 3] {
        let m = data.cam_xmat()[self.cam_id];
        for (w, c) in self.dirs_world.iter_mut().zip(&self.dirs_cam) {
            // cam_xmat is row-major with the camera axes as columns: world = M * cam.
            for (i, wi) in w.iter_mut().enumerate() {
                *wi = m[3 * i] * c[0] + m[3 * i + 1] * c[1] + m[3 * i + 2] * c[2];
            }
        }
        data.cam_xpos()[self.cam_id]
    }

    /// World directions of the pixel rays as of the last `update_rays`/`render`.
    #[cfg(test)]
    pub(crate) fn rays(&self) -> &[[f64; 3]] {
        &self.dirs_world
    }

    /// Renders into `out` (row-major, `IMAGE_HEIGHT` rows of `IMAGE_WIDTH`). `geom_grey[g]` is the
    /// grey of geom `g`; `groups` selects the geom groups the camera sees. Needs up-to-date
    /// kinematics (`cam_xpos`, `cam_xmat`).
    pub fn render<M: mujoco_rs::wrappers::mj_model::traits::ModelType>(
        &mut self,
        data: &mut MjData<M>,
        groups: &[u8; 6],
        geom_grey: &[f32],
        out: &mut [f32; IMAGE_PIXELS],
    ) {
        let pos = self.update_rays(data);
        let (hits, _) = data.multi_ray(
            &pos,
            &self.dirs_world,
            Some(groups),
            true,
            None,
            MAX_RAY_M,
            None,
        );
        let grey = |hit: &Option<usize>| match hit {
            Some(g) => geom_grey.get(*g).copied().unwrap_or(BACKGROUND_GREY),
            None => BACKGROUND_GREY,
        };
        let per_pixel = self.supersample * self.supersample;
        for (px, rays) in out.iter_mut().zip(hits.chunks_exact(per_pixel)) {
            // Fixed summation order: the same hits give the same bits.
            *px = rays.iter().map(grey).sum::<f32>() / per_pixel as f32;
        }
    }
}
