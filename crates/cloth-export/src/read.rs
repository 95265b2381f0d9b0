//! A binary glTF export read back: the scene it was run from (embedded in the asset's extras),
//! and the cloth's positions at every kept frame (the base mesh plus each morph target) on the
//! simulated clock. What `cloth view` draws, and a check that an export holds the run.

use std::path::Path;

use cloth_core::Scene;

use crate::glb::EXTRAS_KEY;

/// What went wrong reading an export; each names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ReadError {
    /// The file.
    pub path: String,
    /// What is wrong.
    pub message: String,
}

/// A run read back from its GLB.
#[derive(Clone, Debug)]
pub struct ExportedRun {
    /// The scene the run was simulated from.
    pub scene: Scene,
    /// The backend that ran it.
    pub backend: String,
    /// Each kept frame: its simulated time (s) and the cloth's positions (m), in grid order.
    pub frames: Vec<(f64, Vec<[f32; 3]>)>,
}

/// Reads a GLB written by [`crate::glb`].
///
/// # Errors
/// A file that cannot be read, is not glTF, or was not written by this workbench.
pub fn read_glb(path: &Path) -> Result<ExportedRun, ReadError> {
    let fail = |message: String| ReadError { path: path.display().to_string(), message };
    let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot read it: {e}")))?;
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(&bytes).map_err(|e| fail(format!("not glTF: {e}")))?;
    let blob = blob.ok_or_else(|| fail("no binary chunk: not a GLB of the workbench".into()))?;
    let run = (document.as_json().asset.extras.as_ref())
        .and_then(|raw| serde_json::from_str::<serde_json::Value>(raw.get()).ok())
        .and_then(|v| v.get(EXTRAS_KEY).cloned())
        .ok_or_else(|| fail(format!("no '{EXTRAS_KEY}' in the asset's extras: not an export of the workbench")))?;
    let scene_ron = run["scene_ron"].as_str().ok_or_else(|| fail("no scene in the extras".into()))?;
    let scene = Scene::from_ron_str(scene_ron).map_err(|e| fail(format!("its scene: {e}")))?;
    let cloth =
        (document.meshes()).find(|m| m.name() == Some("cloth")).ok_or_else(|| fail("no mesh named 'cloth'".into()))?;
    let primitive = cloth.primitives().next().ok_or_else(|| fail("the cloth has no primitive".into()))?;
    let reader = primitive.reader(|_| Some(&blob[..]));
    let base: Vec<[f32; 3]> =
        reader.read_positions().ok_or_else(|| fail("the cloth has no positions".into()))?.collect();
    if base.len() != scene.vertex_count() {
        return Err(fail(format!("{} cloth vertices for a scene of {}", base.len(), scene.vertex_count())));
    }
    // The animation's clock: the time of each kept frame, the base mesh's first.
    let times: Vec<f64> = match document.animations().next().and_then(|a| a.channels().next()) {
        Some(channel) => (channel.reader(|_| Some(&blob[..])).read_inputs())
            .ok_or_else(|| fail("the animation has no times".into()))?
            .map(f64::from)
            .collect(),
        None => vec![0.0],
    };
    let mut frames = vec![(times[0], base.clone())];
    for (k, (positions, _, _)) in reader.read_morph_targets().enumerate() {
        let delta = positions.ok_or_else(|| fail(format!("morph target {k} has no positions")))?;
        let x: Vec<[f32; 3]> = base.iter().zip(delta).map(|(b, d)| [b[0] + d[0], b[1] + d[1], b[2] + d[2]]).collect();
        let time = *times.get(k + 1).ok_or_else(|| fail(format!("no time for morph target {k}")))?;
        frames.push((time, x));
    }
    Ok(ExportedRun { scene, backend: run["backend"].as_str().unwrap_or("unknown").to_string(), frames })
}
