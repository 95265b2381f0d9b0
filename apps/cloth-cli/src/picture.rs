//! The pictures of `cloth run --png` and `--gif`: drawn by the inspector's renderer
//! ([`cloth_view`]) offscreen, on a Vulkan device of their own (lavapipe where there is no GPU),
//! with smooth two-sided shading, every collider, the ground grid and the colour mode; where no
//! Vulkan device is found, by the CPU rasteriser of [`crate::render`] (flat shading, no ground),
//! and the run says so.

use std::path::Path;

use anyhow::{Context, Result};
use cloth_core::{ClothModel, ClothState};
use cloth_view::{ColorMode, OrbitCamera, Source, ViewInputs, ViewRenderer};

/// Where the pictures are drawn.
pub enum Painter {
    /// The inspector's renderer on a device.
    View { context: cloth_wgpu::GpuContext, renderer: Box<ViewRenderer> },
    /// The CPU rasteriser, and why the view could not be used.
    Cpu { why: String },
}

impl Painter {
    /// The inspector's renderer on the first Vulkan device, else the CPU rasteriser.
    pub fn new() -> Self {
        match cloth_wgpu::GpuContext::new(None) {
            Ok(context) => {
                let renderer = Box::new(ViewRenderer::new(&context.device));
                Self::View { context, renderer }
            }
            Err(e) => Self::Cpu { why: e.to_string() },
        }
    }

    /// What draws the pictures, for the run's output.
    pub fn description(&self) -> String {
        match self {
            Self::View { context, .. } => format!("the inspector's renderer on {}", context.adapter_description),
            Self::Cpu { why } => {
                format!("the CPU rasteriser (flat shading, no ground, plain colour: no Vulkan device: {why})")
            }
        }
    }

    /// The state drawn as `width × height` RGBA pixels, row by row from the top.
    ///
    /// # Errors
    /// When the device cannot draw or read the picture back.
    pub fn draw(
        &mut self,
        model: &ClothModel,
        state: &ClothState,
        color_mode: ColorMode,
        [width, height]: [u32; 2],
    ) -> Result<Vec<u8>> {
        match self {
            Self::View { context, renderer } => {
                let camera = framing(model);
                let inputs = ViewInputs {
                    view_proj: camera.view_proj(width as f32 / height as f32),
                    eye: camera.eye(),
                    color_mode,
                    wireframe: false,
                    source: Source::Host(state),
                    time_s: state.time_s,
                    crossed_triangles: &[],
                };
                renderer.render(&context.device, &context.queue, [width, height], model, &inputs);
                renderer.read_pixels(&context.device, &context.queue).map_err(anyhow::Error::msg)
            }
            Self::Cpu { .. } => {
                let rgb = crate::render::render(model, state, width as usize, height as usize);
                Ok(rgb.chunks(3).flat_map(|p| [p[0], p[1], p[2], 255]).collect())
            }
        }
    }
}

/// The inspector's default view direction, framing [`scene_bounds`].
fn framing(model: &ClothModel) -> OrbitCamera {
    let (lo, hi) = scene_bounds(model);
    let extent = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt().max(0.5);
    let target = [0, 1, 2].map(|k| ((lo[k] + hi[k]) / 2.0) as f32);
    OrbitCamera { target, distance: (0.9 * extent) as f32, ..OrbitCamera::default() }
}

/// The box (m, per axis) of the scene's bounded colliders and the cloth's initial rectangle: what
/// both renderers frame, so pictures of one scene compare whatever the cloth did.
pub fn scene_bounds(model: &ClothModel) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut grow = |p: [f64; 3]| {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    };
    for c in &model.scene.colliders {
        if let Some((low, high)) = c.shape.bounds() {
            grow(low);
            grow(high);
        }
    }
    for p in &model.grid.positions {
        grow(*p);
    }
    (lo, hi)
}

/// 8-bit `pixels` of `width × height` in `color` (RGB or RGBA) as a PNG file's bytes.
pub fn encode_png(pixels: &[u8], width: u32, height: u32, color: png::ColorType) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().context("cannot encode the PNG header")?;
    writer.write_image_data(pixels).context("cannot encode the PNG data")?;
    writer.finish().context("cannot encode the PNG")?;
    Ok(bytes)
}

/// Writes the pictures `frames` (RGBA, `width × height`) as an animated GIF that plays them
/// `delay_s` apart and loops.
///
/// # Errors
/// When the file cannot be written (nothing is left under its name).
pub fn write_gif(path: &Path, frames: &[Vec<u8>], [width, height]: [u32; 2], delay_s: f64) -> Result<()> {
    let (w, h) = (u16::try_from(width)?, u16::try_from(height)?);
    let mut bytes = Vec::new();
    {
        let mut encoder = gif::Encoder::new(&mut bytes, w, h, &[]).context("cannot start the GIF")?;
        encoder.set_repeat(gif::Repeat::Infinite).context("cannot encode the GIF")?;
        for pixels in frames {
            let mut rgba = pixels.clone();
            // Speed 10 of 30: a good palette in well under a second a frame at 480 × 360.
            let mut frame = gif::Frame::from_rgba_speed(w, h, &mut rgba, 10);
            frame.delay = (delay_s * 100.0).round().clamp(2.0, 65535.0) as u16;
            encoder.write_frame(&frame).context("cannot encode a GIF frame")?;
        }
    }
    Ok(cloth_backends::output::write_atomically(path, &bytes)?)
}
