//! The 3D view in the window: [`cloth_view`]'s renderer on eframe's device, its texture shown
//! by egui.

use cloth_core::ClothModel;
use eframe::egui_wgpu::RenderState;
use eframe::wgpu;

pub use cloth_view::{ColorMode, Source, ViewInputs};

/// The view's renderer and the egui texture that shows its picture.
pub struct ViewRenderer {
    renderer: cloth_view::ViewRenderer,
    texture_id: Option<eframe::egui::TextureId>,
}

impl ViewRenderer {
    /// Creates the pipelines on eframe's device.
    pub fn new(rs: &RenderState) -> Self {
        Self { renderer: cloth_view::ViewRenderer::new(&rs.device), texture_id: None }
    }

    /// Draws the scene into a `size`-pixel texture and returns its egui id.
    pub fn render(
        &mut self,
        rs: &RenderState,
        size: [u32; 2],
        model: &ClothModel,
        inputs: &ViewInputs<'_>,
    ) -> eframe::egui::TextureId {
        let new_texture = self.renderer.render(&rs.device, &rs.queue, size, model, inputs);
        let texture = self.renderer.texture().expect("just drawn");
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let mut renderer = rs.renderer.write();
        match self.texture_id {
            Some(id) if new_texture => {
                renderer.update_egui_texture_from_wgpu_texture(&rs.device, &view, wgpu::FilterMode::Linear, id);
                id
            }
            Some(id) => id,
            None => {
                let id = renderer.register_native_texture(&rs.device, &view, wgpu::FilterMode::Linear);
                self.texture_id = Some(id);
                id
            }
        }
    }
}
