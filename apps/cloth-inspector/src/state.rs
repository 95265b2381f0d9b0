//! What the inspector remembers between runs (eframe persistence): the edited scene and the
//! view settings. Runtime resources (devices, simulators) live in `app::Runtime`.

use std::path::PathBuf;

use cloth_core::Scene;
use serde::{Deserialize, Serialize};

use crate::render::ColorMode;
use cloth_view::OrbitCamera;

/// Persisted state.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default)]
pub struct PersistedState {
    /// The scene being edited (what the simulator runs, once valid).
    pub scene: Scene,
    /// The scene as last loaded or saved, to know whether there are unsaved edits.
    pub saved_scene: Scene,
    /// File the scene came from or was saved to.
    pub scene_path: Option<PathBuf>,
    /// Backend name.
    pub backend: String,
    /// The 3D view's camera.
    pub camera: OrbitCamera,
    /// Cloth colouring.
    pub color_mode: ColorMode,
    /// Draw the springs' grid over the cloth.
    pub wireframe: bool,
    /// Simulation running.
    pub playing: bool,
    /// Simulated frames per displayed frame.
    pub speed: f32,
}

impl Default for PersistedState {
    fn default() -> Self {
        Self {
            scene: Scene::default(),
            saved_scene: Scene::default(),
            scene_path: None,
            backend: "wgpu".into(),
            camera: OrbitCamera::default(),
            color_mode: ColorMode::Plain,
            wireframe: false,
            playing: true,
            speed: 1.0,
        }
    }
}

impl PersistedState {
    /// Whether the scene differs from the last loaded or saved one.
    pub fn has_unsaved_edits(&self) -> bool {
        self.scene != self.saved_scene
    }
}
