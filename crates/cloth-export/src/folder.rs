//! A run as a folder a notebook or a mesh tool reads:
//!
//! * `frame_NNNNN.obj`: the cloth at each kept frame (`NNNNN` the frame's number, 0 the start):
//!   one `v` line per vertex in grid order, its normal, two triangles a cell
//!   ([`cloth_core::export::wavefront_obj`]);
//! * `colliders.obj`: every collider at time 0, one `o` object each;
//! * `diagnostics.csv`: a row per kept frame: its number, the simulated time (s), the kinetic and
//!   elastic energy (J), the deepest penetration into any collider (m) and the self-intersections
//!   (edge–triangle crossings; empty where the cloth could not be counted), and the total energy
//!   (J: kinetic, elastic, gravitational and the colliders' penalty, what the stability suite
//!   bounds; last, so readers of the earlier columns keep their indices).
//!
//! Each file is written whole (a temporary file renamed into place); the CSV last, so a folder
//! with a `diagnostics.csv` holds a finished export.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cloth_core::colliders::Collider;
use cloth_core::real::Vec3;
use cloth_core::{ClothModel, ClothState, Effect, Energy, Scene};

use cloth_core::output::{cannot_write, temporary_beside, write_atomically};

use crate::{ExportError, ExportPlan, ExportSummary};

/// The CSV's header.
pub const CSV_HEADER: &str =
    "frame,time_s,kinetic_energy_j,elastic_energy_j,deepest_penetration_m,self_intersections,total_energy_j";

/// Checks that `dir` is, or can be made, a folder that takes new files.
pub(crate) fn check_writable(dir: &Path) -> std::io::Result<()> {
    // Without its trailing `/`: a file named so is then found as a file.
    let dir = dir.components().as_path();
    if dir.exists() && !dir.is_dir() {
        return Err(cannot_write(dir, "it is a file, not a folder", std::io::ErrorKind::NotADirectory));
    }
    std::fs::create_dir_all(dir).map_err(|e| cannot_write(dir, &e, e.kind()))?;
    let probe = temporary_beside(&dir.join("probe"));
    std::fs::write(&probe, b"").and_then(|()| std::fs::remove_file(&probe)).map_err(|e| cannot_write(dir, &e, e.kind()))
}

/// Deepest penetration of `state` into any collider of `scene` at the state's time, `max −φ`, m
/// (0 when none).
pub fn deepest_penetration(scene: &Scene, state: &ClothState) -> f64 {
    if !scene.effects.contains(Effect::Contact) {
        return 0.0;
    }
    let moving = scene.effects.contains(Effect::MovingColliders);
    let mut deepest = 0.0f64;
    for spec in &scene.colliders {
        let c = Collider::<f64>::of(spec);
        let (center, _) = c.at(state.time_s, moving);
        for p in &state.positions {
            deepest = deepest.max(-c.distance(center, Vec3::from_f64(p.map(f64::from))));
        }
    }
    deepest
}

/// A folder export under way.
pub struct FolderWriter {
    dir: PathBuf,
    model: ClothModel,
    source: String,
    csv: String,
    every: u32,
    kept: u64,
    planned: u64,
    bytes: u64,
}

impl FolderWriter {
    /// Creates the folder, writes the colliders and the first kept frame.
    pub(crate) fn start(
        dir: &Path,
        plan: &ExportPlan,
        scene: &Scene,
        initial: &ClothState,
        source: &str,
    ) -> Result<Self, ExportError> {
        check_writable(dir)?;
        let mut writer = Self {
            dir: dir.to_path_buf(),
            model: ClothModel::new(scene),
            source: source.to_string(),
            csv: format!("{CSV_HEADER}\n"),
            every: plan.every,
            kept: 0,
            planned: plan.kept_frames(),
            bytes: 0,
        };
        let mut colliders = format!("# colliders of '{}' at t = 0 s, m\n", scene.name);
        let mut first = 1;
        for index in 0..scene.colliders.len() {
            let mesh = cloth_core::tessellation::collider(scene, index, 0.0);
            let _ = writeln!(colliders, "o collider_{index}_{}", scene.colliders[index].kind().name());
            for p in &mesh.positions {
                let _ = writeln!(colliders, "v {} {} {}", p[0], p[1], p[2]);
            }
            for n in &mesh.normals {
                let _ = writeln!(colliders, "vn {:.6} {:.6} {:.6}", n[0], n[1], n[2]);
            }
            for t in mesh.indices.chunks(3) {
                let [a, b, c] = [t[0], t[1], t[2]].map(|k| k + first);
                let _ = writeln!(colliders, "f {a}//{a} {b}//{b} {c}//{c}");
            }
            first += mesh.positions.len() as u32;
        }
        writer.write("colliders.obj", colliders.as_bytes())?;
        writer.record(initial)?;
        Ok(writer)
    }

    fn write(&mut self, name: &str, bytes: &[u8]) -> Result<(), ExportError> {
        write_atomically(&self.dir.join(name), bytes)?;
        self.bytes += bytes.len() as u64;
        Ok(())
    }

    /// Writes the next kept frame's OBJ and its diagnostics row.
    pub(crate) fn record(&mut self, state: &ClothState) -> Result<(), ExportError> {
        let scene = &self.model.scene;
        if state.positions.len() != scene.vertex_count() {
            return Err(ExportError::WrongState { expected: scene.vertex_count(), got: state.positions.len() });
        }
        if self.kept >= self.planned {
            return Err(ExportError::TooManyFrames { planned: self.planned });
        }
        let [nx, ny] = scene.cloth.resolution;
        let frame = self.kept * u64::from(self.every);
        let comment = format!(
            "cloth '{}': frame {frame}, {nx} x {ny} vertices at t = {:.6} s on {}, m\ntwo triangles a cell, split \
             along (i, j)-(i+1, j+1)",
            scene.name, state.time_s, self.source
        );
        let obj = cloth_core::export::wavefront_obj(&state.positions, nx, ny, &comment);
        let energy = Energy::of(&self.model, state);
        let crossings = cloth_core::intersections::count(&state.positions, nx, ny).ok();
        let _ = writeln!(
            self.csv,
            "{frame},{},{},{},{},{},{}",
            state.time_s,
            energy.kinetic,
            energy.elastic.iter().sum::<f64>(),
            deepest_penetration(scene, state),
            crossings.map_or(String::new(), |c| c.to_string()),
            energy.total()
        );
        self.write(&format!("frame_{frame:05}.obj"), obj.as_bytes())?;
        self.kept += 1;
        Ok(())
    }

    /// Writes the CSV.
    pub(crate) fn finish(mut self) -> Result<ExportSummary, ExportError> {
        let csv = std::mem::take(&mut self.csv);
        self.write("diagnostics.csv", csv.as_bytes())?;
        Ok(ExportSummary { path: self.dir, frames: self.kept, bytes: self.bytes })
    }
}
