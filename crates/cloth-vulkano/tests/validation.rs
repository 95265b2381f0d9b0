//! Validation layers: on in debug test runs when installed, and any message fails the run.

use cloth_core::{Scene, SimError, Simulator};
use cloth_vulkano::VulkanoSimulator;

fn small_scene() -> Scene {
    let mut scene = Scene::default();
    scene.cloth.resolution = [4, 3];
    scene
}

fn simulator() -> Option<VulkanoSimulator> {
    match VulkanoSimulator::new(&small_scene()) {
        Ok(sim) => Some(sim),
        Err(SimError::Unavailable { reason, .. }) if std::env::var_os("CI").is_none() => {
            eprintln!("SKIPPED on backend vulkano: {reason}");
            None
        }
        Err(e) => panic!("vulkano could not start: {e}"),
    }
}

/// One test, in order: the messages are shared by the process's one instance, so an injected
/// message would fail any simulator running beside it.
#[test]
fn validation_is_on_in_debug_runs_and_any_message_fails_the_next_operation() {
    validation_is_on_in_debug_runs_when_the_layer_is_installed();
    a_validation_message_fails_the_next_operation();
}

fn validation_is_on_in_debug_runs_when_the_layer_is_installed() {
    let Some(sim) = simulator() else { return };
    let installed = ["/usr/share/vulkan/explicit_layer.d", "/etc/vulkan/explicit_layer.d"]
        .iter()
        .any(|d| std::path::Path::new(d).join("VkLayer_khronos_validation.json").exists());
    if cfg!(debug_assertions) && installed {
        assert!(sim.backend().context().validation, "the Khronos validation layer is installed but not enabled");
        assert!(sim.adapter_name().ends_with("validation on"));
    }
}

fn a_validation_message_fails_the_next_operation() {
    let Some(mut sim) = simulator() else { return };
    sim.advance(2).unwrap();
    sim.backend().context().messages.lock().unwrap().push("ERROR: a message injected by this test".into());
    let err = sim.advance(1).unwrap_err().to_string();
    sim.backend().context().messages.lock().unwrap().clear();
    assert!(err.contains("Vulkan validation: ERROR: a message injected by this test"), "{err}");
}
