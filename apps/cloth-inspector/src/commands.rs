//! Actions that change the world, queued while the UI is drawn and applied after the frame.

use std::path::PathBuf;

/// One action.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Restart the current scene from its initial state.
    Reset,
    /// Hand the running cloth to another backend.
    SwitchBackend(String),
    /// Load a scene file (validation errors are shown; nothing is opened then).
    OpenScene(PathBuf),
    /// Save the edited scene (atomically: temporary file, then rename).
    SaveScene(PathBuf),
    /// Advance exactly one frame (while paused).
    StepOnce,
    /// Hand the running cloth to a simulator of the same backend with this GPU tuning.
    ApplyTuning(cloth_gpu::GpuTuning),
    /// Advance one frame with a GPU timestamp after every dispatch, and show where its time went.
    ProfileFrame,
}
