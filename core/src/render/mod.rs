//! Stage 6: render AOV images of a scene with any intersector, on the CPU (rayon).
//!
//! Every pixel's rays and random numbers depend only on (pixel, sample, seed), so the image is
//! the same for 1 or N threads. AOVs: `depth` (distance along the camera ray), `normal`
//! (world-space shading normal, the asset's own frame), `mask` (coverage), `uv`, `steps`
//! (marching/traversal steps), `prism` (prism id + 1, 0 = miss). `beauty` is not an AOV of
//! this pass: it is path traced by `beauty` (and orchestrated with the AOVs by `lookdev`).

pub mod beauty;
pub mod camera;
pub mod contact_sheet;
pub mod cutout;
pub mod denoise;
pub mod env;
pub mod ggx_tables;
mod ggx_tables_data;
pub mod job;
pub mod lights;
pub mod lookdev;
pub mod output;
pub mod shading;

use crate::rng::{self, Purpose};
use crate::trace::{Intersector, RayContext};
use camera::Camera;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Aov {
    Depth,
    Normal,
    Mask,
    Uv,
    Steps,
    Prism,
    /// The path-traced picture (`render::beauty`), RGBA.
    Beauty,
}

impl Aov {
    pub const ALL: [Aov; 7] = [
        Aov::Depth,
        Aov::Normal,
        Aov::Mask,
        Aov::Uv,
        Aov::Steps,
        Aov::Prism,
        Aov::Beauty,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Normal => "normal",
            Aov::Mask => "mask",
            Aov::Uv => "uv",
            Aov::Steps => "steps",
            Aov::Prism => "prism",
            Aov::Beauty => "beauty",
        }
    }
    pub fn channels(self) -> usize {
        match self {
            Aov::Normal => 3,
            Aov::Uv => 2,
            Aov::Beauty => 4,
            _ => 1,
        }
    }
}

impl std::str::FromStr for Aov {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Aov::ALL
            .iter()
            .find(|a| a.name() == s)
            .copied()
            .ok_or_else(|| {
                format!(
                    "unknown AOV '{s}' (expected depth, normal, mask, uv, steps, prism or beauty)"
                )
            })
    }
}

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u32,
}

/// One frame of AOVs, all channels interleaved per AOV, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct AovImage {
    pub width: u32,
    pub height: u32,
    pub depth: Vec<f32>,
    pub normal: Vec<Vec3>,
    pub mask: Vec<f32>,
    pub uv: Vec<Vec2>,
    pub steps: Vec<f32>,
    pub prism: Vec<f32>,
    /// Total rays traced and marching steps, for statistics.
    pub rays: u64,
    pub total_steps: u64,
}

impl AovImage {
    /// A `width`×`height` image of zeros (no hits), to be filled in place, e.g. tile by tile.
    pub fn blank(width: u32, height: u32) -> AovImage {
        let n = width as usize * height as usize;
        AovImage {
            width,
            height,
            depth: vec![0.0; n],
            normal: vec![Vec3::ZERO; n],
            mask: vec![0.0; n],
            uv: vec![Vec2::ZERO; n],
            steps: vec![0.0; n],
            prism: vec![0.0; n],
            rays: 0,
            total_steps: 0,
        }
    }

    /// The AOV as rows of `channels()` floats (empty for `Beauty`, which is not in this image).
    pub fn channel_data(&self, aov: Aov) -> Vec<f32> {
        match aov {
            Aov::Depth => self.depth.clone(),
            Aov::Mask => self.mask.clone(),
            Aov::Steps => self.steps.clone(),
            Aov::Prism => self.prism.clone(),
            Aov::Normal => self.normal.iter().flat_map(|n| n.to_array()).collect(),
            Aov::Uv => self.uv.iter().flat_map(|u| u.to_array()).collect(),
            Aov::Beauty => Vec::new(),
        }
    }
}

#[derive(Clone, Copy, Default)]
struct PixelAcc {
    depth: f32,
    normal: Vec3,
    uv: Vec2,
    steps: f32,
    hits: u32,
    prism: u32,
}

/// Render one frame. `progress` is called with the number of rows finished so far.
pub fn render_aovs(
    intersector: &dyn Intersector,
    cam: &Camera,
    s: &RenderSettings,
    progress: &(dyn Fn(usize) + Sync),
) -> AovImage {
    let (w, h) = (s.width, s.height);
    let done = AtomicUsize::new(0);
    let raster = cam.raster(w, h);
    let rows: Vec<Vec<PixelAcc>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| {
                    let pixel = y * w + x;
                    let mut acc = PixelAcc::default();
                    for sample in 0..s.spp {
                        let jitter = if s.spp == 1 {
                            Vec2::splat(0.5)
                        } else {
                            Vec2::new(
                                rng::random(pixel, sample, 0, Purpose::PixelJitter, s.seed),
                                rng::random(pixel, sample, 1, Purpose::PixelJitter, s.seed),
                            )
                        };
                        let ray = raster.ray(Vec2::new(x as f32, y as f32) + jitter);
                        let ctx = RayContext {
                            pixel,
                            sample,
                            bounce: 0,
                            seed: s.seed,
                        };
                        if let Some(hit) = intersector.intersect(&ray, &ctx) {
                            acc.hits += 1;
                            acc.depth += hit.t;
                            acc.normal += hit.shading_normal;
                            acc.uv += hit.uv;
                            acc.steps += hit.steps as f32;
                            if acc.hits == 1 {
                                acc.prism = hit.prism + 1;
                            }
                        }
                    }
                    acc
                })
                .collect();
            progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            row
        })
        .collect();
    let n = (w * h) as usize;
    let mut img = AovImage {
        width: w,
        height: h,
        depth: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        mask: Vec::with_capacity(n),
        uv: Vec::with_capacity(n),
        steps: Vec::with_capacity(n),
        prism: Vec::with_capacity(n),
        rays: n as u64 * s.spp as u64,
        total_steps: 0,
    };
    for acc in rows.into_iter().flatten() {
        let k = acc.hits.max(1) as f32;
        img.depth
            .push(if acc.hits > 0 { acc.depth / k } else { 0.0 });
        img.normal.push(acc.normal.normalize_or_zero());
        img.mask.push(acc.hits as f32 / s.spp as f32);
        img.uv.push(acc.uv / k);
        img.steps.push(acc.steps / s.spp as f32);
        img.total_steps += (acc.steps) as u64;
        img.prism.push(acc.prism as f32);
    }
    img
}
