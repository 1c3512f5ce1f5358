//! Ray-traced stereo images and per-pixel ground truth.
//!
//! One primary ray per pixel; a water hit spawns one reflection ray (no further water bounces), mixed
//! with the water's own colour by a Schlick Fresnel term. So reflected sky shows the sky's near-zero
//! disparity on the water, and reflected objects appear below the surface, as with real stereo.
//! All textures are functions of world (or object) coordinates, so both eyes see the same texture.
//! Rows are rendered in parallel with rayon; each pixel is independent and deterministic.

mod scene;
mod shade;
mod sight;
mod skycache;

use crate::camera::{Camera, Encoding, StereoHead};
use crate::math::Pose;
use crate::noise::{hash32, unit};
use crate::rectify::RectifiedView;
use crate::world::{Label, World};
use rayon::prelude::*;
use scene::{Ray, Scene};
use shade::{Surface, Tracer};
use skycache::SkyCache;

pub use sight::Sight;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{what} buffer holds {got} elements, head `{head}` needs {expected}")]
    BufferSize {
        what: &'static str,
        head: String,
        got: usize,
        expected: usize,
    },
    #[error("head `{head}`: {source}")]
    Rectify {
        head: String,
        source: crate::rectify::RectifyError,
    },
}

/// Reusable renderer: keeps the instantiated scene between frames (no per-frame allocation once the
/// buffers have grown to the scene's size).
#[derive(Default)]
pub struct Renderer {
    scene: Scene,
    sky: SkyCache,
    scene_time: Option<f64>,
}

impl Renderer {
    pub fn new() -> Renderer {
        Renderer::default()
    }

    /// Places moving objects and moves clouds to time `t` (no-op if already at `t`).
    pub fn prepare(&mut self, world: &World, t: f64) {
        if self.scene_time != Some(t) {
            self.scene.build(world, t);
            self.sky.update(&world.sky, t);
            self.scene_time = Some(t);
        }
    }

    /// Renders the left and right images of `head` on a vehicle at `body` (`world_from_body`) at time
    /// `t` into caller-provided buffers of `head.image_len()` bytes (row-major, tightly packed).
    pub fn render_pair(
        &mut self,
        world: &World,
        head: &StereoHead,
        body: &Pose,
        t: f64,
        left: &mut [u8],
        right: &mut [u8],
    ) -> Result<(), RenderError> {
        for buf in [&*left, &*right] {
            check_len("image", head, buf.len(), head.image_len())?;
        }
        self.prepare(world, t);
        let [cl, cr] = head.cameras(body);
        let tracer = Tracer::new(world, &self.scene, &self.sky, t as f32, cl.pixel_angle());
        render_image(&tracer, &cl, head, t, left);
        render_image(&tracer, &cr, head, t, right);
        Ok(())
    }

    /// Renders what camera `cam` (of `head`, for the noise and encoding) sees at time `t`; `out`
    /// holds `cam.width * cam.height * channels` bytes. Used to look through the rectified view.
    pub fn render_camera(
        &mut self,
        world: &World,
        head: &StereoHead,
        cam: &Camera,
        t: f64,
        out: &mut [u8],
    ) -> Result<(), RenderError> {
        let n = cam.width as usize * cam.height as usize * head.encoding.channels();
        check_len("image", head, out.len(), n)?;
        self.prepare(world, t);
        let tracer = Tracer::new(world, &self.scene, &self.sky, t as f32, cam.pixel_angle());
        render_image(&tracer, cam, head, t, out);
        Ok(())
    }

    /// Ground truth in the rectified left view `view` of `head` (see [`StereoHead::rectified`];
    /// for an untoed, undistorted head it is the left image itself): disparity `f * B / Z` in
    /// pixels (0 for sky, which is at infinity) and a [`Label`] per pixel, `view.width *
    /// view.height` each. Water pixels carry the water surface's own disparity and label, not
    /// those of what it reflects.
    #[allow(clippy::too_many_arguments)]
    pub fn render_truth(
        &mut self,
        world: &World,
        head: &StereoHead,
        view: &RectifiedView,
        body: &Pose,
        t: f64,
        disparity: &mut [f32],
        labels: &mut [u8],
    ) -> Result<(), RenderError> {
        let n = view.width * view.height;
        check_len("disparity", head, disparity.len(), n)?;
        check_len("label", head, labels.len(), n)?;
        self.prepare(world, t);
        let cam = head.rectified_camera(view, body);
        let tracer = Tracer::new(world, &self.scene, &self.sky, t as f32, cam.pixel_angle());
        let w = cam.width as usize;
        let fb = cam.f * cam.baseline;
        disparity
            .par_chunks_mut(w)
            .zip(labels.par_chunks_mut(w))
            .enumerate()
            .for_each(|(v, (drow, lrow))| {
                for u in 0..w {
                    let d = cam.ray(u as f32, v as f32);
                    let len = d.norm();
                    let hit = tracer.trace(&Ray::new(cam.pos, d / len));
                    let label = tracer.label(&hit, cam.pos + d / len * hit.t);
                    lrow[u] = label as u8;
                    // The ray direction has unit optical-axis component, so depth Z = t / |d|.
                    drow[u] = if matches!(hit.surface, Surface::Sky) {
                        0.0
                    } else {
                        fb * len / hit.t
                    };
                }
            });
        Ok(())
    }
}

fn check_len(
    what: &'static str,
    head: &StereoHead,
    got: usize,
    expected: usize,
) -> Result<(), RenderError> {
    if got == expected {
        Ok(())
    } else {
        Err(RenderError::BufferSize {
            what,
            head: head.name.clone(),
            got,
            expected,
        })
    }
}

fn render_image(tracer: &Tracer, cam: &Camera, head: &StereoHead, t: f64, out: &mut [u8]) {
    let w = cam.width as usize;
    let ch = head.encoding.channels();
    // Per-frame, per-eye noise key: the same time and seed give the same noise.
    let frame_key = hash32((t * 1e3).round() as i64 as u32 ^ hash32(tracer.seed() ^ cam.index));
    let noise_amp = head.pixel_noise * 6f32.sqrt() * 255.0f32.recip();
    out.par_chunks_mut(w * ch).enumerate().for_each(|(v, row)| {
        let row_key = hash32(frame_key ^ (v as u32).wrapping_mul(0x9e37_79b9));
        for u in 0..w {
            let d = cam.ray(u as f32, v as f32).normalize();
            let c = tracer.radiance(cam.pos, d);
            // Triangular noise (sum of two uniforms) with the configured standard deviation.
            let h = hash32(row_key ^ (u as u32).wrapping_mul(0x85eb_ca6b));
            let n = (unit(h) + unit(hash32(h)) - 1.0) * noise_amp;
            let px = &mut row[u * ch..(u + 1) * ch];
            match head.encoding {
                Encoding::Mono8 => {
                    let y = 0.299 * c.x + 0.587 * c.y + 0.114 * c.z;
                    px[0] = to_u8(y, n);
                }
                Encoding::Rgb8 => {
                    px[0] = to_u8(c.x, n);
                    px[1] = to_u8(c.y, n);
                    px[2] = to_u8(c.z, n);
                }
            }
        }
    });
}

/// Linear radiance to an 8-bit value with a gamma-2 curve (square root), plus noise.
#[inline(always)]
fn to_u8(linear: f32, noise: f32) -> u8 {
    let v = linear.clamp(0.0, 1.0).sqrt() + noise;
    (v * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

/// Converts a label buffer to an RGB visualisation (for PNG output and docs).
pub fn labels_to_rgb(labels: &[u8], out: &mut [u8]) {
    for (l, px) in labels.iter().zip(out.chunks_exact_mut(3)) {
        let c = Label::ALL
            .get(*l as usize)
            .map(|l| l.color())
            .unwrap_or([255, 0, 255]);
        px.copy_from_slice(&c);
    }
}
