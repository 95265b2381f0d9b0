//! Exports written and read back: the glTF file gives the simulated positions at every kept frame
//! (read with the `gltf` crate), the Khronos validator finds no error in it, and no failure (a bad
//! path, a full disk, an export abandoned half-way) leaves a file under the final name.

use std::path::{Path, PathBuf};
use std::process::Command;

use cloth_core::{ClothState, CpuSimulator, Scene, Simulator};
use cloth_export::{ExportPlan, Exporter};

fn scene(name: &str, resolution: [u32; 2]) -> Scene {
    let path = format!("{}/../../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(Path::new(&path)).unwrap();
    scene.cloth.resolution = resolution;
    scene.validate().unwrap();
    scene
}

/// A fresh folder for one test.
fn folder(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cloth-export-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

/// Runs `frames` frames of `scene` on the CPU into `path`, keeping every `every`-th; returns the
/// kept states.
fn export(scene: &Scene, path: &Path, frames: u32, every: u32) -> Vec<ClothState> {
    let plan = ExportPlan::new(path, scene, frames, every).unwrap();
    let mut sim = CpuSimulator::new(scene).unwrap();
    let mut kept = vec![sim.read_state().unwrap()];
    let mut exporter = Exporter::start(&plan, scene, &kept[0], "cpu").unwrap();
    for done in 1..=frames {
        sim.advance(1).unwrap();
        if plan.keeps(done) {
            kept.push(sim.read_state().unwrap());
            exporter.record(kept.last().unwrap()).unwrap();
        }
    }
    let summary = exporter.finish().unwrap();
    assert_eq!(summary.frames, kept.len() as u64);
    kept
}

#[test]
fn a_glb_read_back_gives_the_simulated_positions_at_every_kept_frame() {
    let dir = folder("read-back");
    let scene = scene("drape.ron", [12, 10]);
    let path = dir.join("drape.glb");
    let kept = export(&scene, &path, 9, 2);
    assert_eq!(kept.len(), 5, "the start and frames 2, 4, 6 and 8");
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let buffers = [blob.expect("a GLB's binary chunk")];
    let cloth = document.meshes().find(|m| m.name() == Some("cloth")).expect("a mesh named cloth");
    let primitive = cloth.primitives().next().unwrap();
    let reader = primitive.reader(|b| Some(&buffers[b.index()][..]));
    let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    assert_eq!(base, kept[0].positions, "the base mesh is the first state, exactly");
    assert_eq!(reader.read_normals().unwrap().count(), base.len());
    let uv: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
    assert_eq!((uv[0], uv[11], uv[119]), ([0.0, 0.0], [1.0, 0.0], [1.0, 1.0]));
    assert_eq!(reader.read_indices().unwrap().into_u32().count(), 3 * 2 * 11 * 9);
    let targets: Vec<Vec<[f32; 3]>> =
        reader.read_morph_targets().map(|(p, _, _)| p.expect("a position delta").collect()).collect();
    assert_eq!(targets.len(), kept.len() - 1);
    // Base + delta restores each kept state within the rounding of one f32 subtraction and one
    // addition (a few ulps of the coordinates, which are under 4 m).
    let mut worst = 0.0f32;
    for (target, state) in targets.iter().zip(&kept[1..]) {
        for ((b, d), x) in base.iter().zip(target).zip(&state.positions) {
            for k in 0..3 {
                worst = worst.max((b[k] + d[k] - x[k]).abs());
            }
        }
    }
    assert!(worst <= 4.0 * f32::EPSILON * 4.0, "base + target differs from the state by {worst} m");
    // The cloth moved: the targets are not all zero.
    assert!(targets.last().unwrap().iter().any(|d| d[1] < -1e-3), "the cloth falls");
    // The clock is the simulated time; the weights select target k at kept frame k.
    let animation = document.animations().next().expect("an animation");
    let channel = animation.channels().find(|c| c.target().node().mesh().map(|m| m.index()) == Some(cloth.index()));
    let reader = channel.expect("a channel on the cloth").reader(|b| Some(&buffers[b.index()][..]));
    let times: Vec<f32> = reader.read_inputs().unwrap().collect();
    assert_eq!(times, kept.iter().map(|s| s.time_s as f32).collect::<Vec<_>>());
    let Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(weights)) = reader.read_outputs() else {
        panic!("the cloth's channel drives its morph target weights")
    };
    let weights: Vec<f32> = weights.into_f32().collect();
    let m = targets.len();
    for (k, row) in weights.chunks(m).enumerate() {
        let expected: Vec<f32> = (0..m).map(|t| if k > 0 && t == k - 1 { 1.0 } else { 0.0 }).collect();
        assert_eq!(row, expected, "weights at kept frame {k}");
    }
    // The sphere is a mesh of its own.
    assert!(document.meshes().any(|m| m.name().is_some_and(|n| n.starts_with("collider 0 (sphere)"))));
    // The workbench's own reader gives the same frames, and the scene they were run from.
    let run = cloth_export::read::read_glb(&path).unwrap();
    assert_eq!(run.scene, scene);
    assert_eq!(run.frames.len(), kept.len());
    for ((t, x), state) in run.frames.iter().zip(&kept) {
        assert_eq!(*t, state.time_s as f32 as f64);
        let worst = (x.iter().zip(&state.positions))
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst <= 16.0 * f32::EPSILON, "{worst}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_folder_holds_an_obj_a_kept_frame_the_colliders_and_the_diagnostics() {
    let dir = folder("folder");
    let scene = scene("drape.ron", [8, 6]);
    let out = dir.join("run/");
    let kept = export(&scene, &out, 4, 2);
    assert_eq!(
        names_in(&out),
        ["colliders.obj", "diagnostics.csv", "frame_00000.obj", "frame_00002.obj", "frame_00004.obj"]
    );
    let frame = std::fs::read_to_string(out.join("frame_00004.obj")).unwrap();
    let vertices: Vec<&str> = frame.lines().filter(|l| l.starts_with("v ")).collect();
    assert_eq!(vertices.len(), 48);
    let first: Vec<f32> = vertices[0][2..].split(' ').map(|x| x.parse().unwrap()).collect();
    assert_eq!(first, kept[2].positions[0], "OBJ coordinates are the state's, exactly (shortest round trip)");
    assert!(std::fs::read_to_string(out.join("colliders.obj")).unwrap().contains("o collider_0_sphere"));
    let csv = std::fs::read_to_string(out.join("diagnostics.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], cloth_export::folder::CSV_HEADER);
    assert_eq!(rows.len(), 4);
    let last: Vec<&str> = rows[3].split(',').collect();
    assert_eq!(last[0], "4");
    assert_eq!(last[1].parse::<f64>().unwrap(), kept[2].time_s);
    assert!(last[2].parse::<f64>().unwrap() > 0.0, "the falling cloth has kinetic energy");
    assert_eq!(last[5], "0", "a flat falling cloth does not pass through itself");
    let model = cloth_core::ClothModel::new(&scene);
    let total = cloth_core::Energy::of(&model, &kept[2]).total();
    assert_eq!(last[6].parse::<f64>().unwrap(), total, "the total energy is the state's");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The Khronos validator's report on `files`, one JSON line each (`tests/gltf-validator`).
fn validate(files: &[PathBuf]) -> Vec<String> {
    let tool = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/gltf-validator");
    assert!(
        tool.join("node_modules/gltf-validator").is_dir(),
        "the glTF validator is not installed: run `cargo xtask setup` (npm ci in {})",
        tool.display()
    );
    let output = Command::new("node")
        .arg(tool.join("validate.mjs"))
        .args(files)
        .output()
        .expect("node runs (cargo xtask setup installs it)");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.code().is_some_and(|c| c <= 1),
        "the validator failed: {}\n{stdout}",
        String::from_utf8_lossy(&output.stderr)
    );
    stdout.lines().map(str::to_string).collect()
}

#[test]
fn the_khronos_validator_finds_no_error_in_three_exported_scenes() {
    let dir = folder("validator");
    let mut files = Vec::new();
    for (name, grid, frames) in [("drape.ron", [16, 16], 6), ("flag.ron", [12, 8], 6), ("heap.ron", [12, 12], 4)] {
        let path = dir.join(name.replace(".ron", ".glb"));
        export(&scene(name, grid), &path, frames, 1);
        files.push(path);
    }
    // A file cut short: the validator must see it, or its silence above proves nothing.
    let cut = dir.join("cut.glb");
    std::fs::write(&cut, &std::fs::read(&files[0]).unwrap()[..600]).unwrap();
    files.push(cut);
    let reports = validate(&files);
    assert_eq!(reports.len(), 4, "{reports:?}");
    for report in &reports[..3] {
        eprintln!("{report}");
        assert!(report.contains("\"errors\":0,"), "{report}");
    }
    assert!(!reports[3].contains("\"errors\":0,"), "{}", reports[3]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_targets_are_refused_before_the_run() {
    let scene = scene("drape.ron", [8, 8]);
    let e = ExportPlan::new(Path::new("/nonexistent-folder/run.glb"), &scene, 4, 1).unwrap_err().to_string();
    assert!(e.starts_with("cannot write /nonexistent-folder/run.glb: "), "{e}");
    let e = ExportPlan::new(Path::new("run.gltf"), &scene, 4, 1).unwrap_err().to_string();
    assert!(e.contains("give a file ending in .glb") && e.contains("run.gltf"), "{e}");
    let e = ExportPlan::new(Path::new("run.glb"), &scene, 4, 0).unwrap_err().to_string();
    assert!(e.contains("--every 0"), "{e}");
    let dir = folder("bad-targets");
    let file = dir.join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let e = ExportPlan::new(&file.join(""), &scene, 4, 1).unwrap_err().to_string();
    assert!(e.contains("a-file: it is a file, not a folder"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A 512 KiB tmpfs mounted for the life of the value.
struct TinyDisk(PathBuf);

impl TinyDisk {
    fn mount(test: &str) -> Self {
        let dir = folder(test);
        let status = Command::new("mount").args(["-t", "tmpfs", "-o", "size=512k", "tmpfs"]).arg(&dir).status();
        assert!(
            status.is_ok_and(|s| s.success()),
            "cannot mount a 512 KiB tmpfs on {} (the full-disk test runs as root, as CI does)",
            dir.display()
        );
        Self(dir)
    }
}

impl Drop for TinyDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn a_full_disk_leaves_no_file_under_the_final_name() {
    let disk = TinyDisk::mount("full-disk");
    // 32² vertices: 24 KiB a kept frame in glTF, over 100 KiB as OBJ: 30 frames fill 512 KiB.
    let scene = scene("drape.ron", [32, 32]);
    for target in ["run.glb", "frames/"] {
        let path = disk.0.join(target);
        let plan = ExportPlan::new(&path, &scene, 30, 1).unwrap();
        let mut sim = CpuSimulator::new(&scene).unwrap();
        let result = (|| {
            let mut exporter = Exporter::start(&plan, &scene, &sim.read_state().unwrap(), "cpu")?;
            for _ in 0..30 {
                sim.advance(1).unwrap();
                exporter.record(&sim.read_state().unwrap())?;
            }
            exporter.finish()
        })();
        let e = result.expect_err("512 KiB cannot hold the export").to_string();
        assert!(e.contains("No space left on device") && e.contains(&disk.0.display().to_string()), "{e}");
        match target {
            // Neither the file nor a temporary one is left.
            "run.glb" => assert!(names_in(&disk.0).is_empty(), "{:?}", names_in(&disk.0)),
            // The frames written are whole, the one that did not fit absent, and no CSV: the
            // folder is not a finished export.
            _ => {
                let names = names_in(&path);
                assert!(names.iter().all(|n| n.ends_with(".obj")), "{names:?}");
                assert!(names.len() >= 2, "the colliders and the first frame fit: {names:?}");
                for name in names.iter().filter(|n| n.starts_with("frame_")) {
                    let text = std::fs::read_to_string(path.join(name)).unwrap();
                    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 32 * 32, "{name}");
                    assert!(text.ends_with('\n'));
                }
            }
        }
    }
}

#[test]
fn an_export_abandoned_half_way_leaves_nothing_behind() {
    let dir = folder("abandoned");
    let scene = scene("drape.ron", [16, 16]);
    let path = dir.join("run.glb");
    let plan = ExportPlan::new(&path, &scene, 10, 1).unwrap();
    let mut sim = CpuSimulator::new(&scene).unwrap();
    let mut exporter = Exporter::start(&plan, &scene, &sim.read_state().unwrap(), "cpu").unwrap();
    for _ in 0..3 {
        sim.advance(1).unwrap();
        exporter.record(&sim.read_state().unwrap()).unwrap();
    }
    assert_eq!(names_in(&dir).len(), 1, "the binary chunk is spilled to one temporary file");
    drop(exporter);
    assert!(names_in(&dir).is_empty(), "{:?}", names_in(&dir));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_state_that_is_not_finite_abandons_the_export() {
    let dir = folder("not-finite");
    let scene = scene("drape.ron", [8, 8]);
    let path = dir.join("run.glb");
    let plan = ExportPlan::new(&path, &scene, 4, 1).unwrap();
    let mut state = CpuSimulator::new(&scene).unwrap().read_state().unwrap();
    let mut exporter = Exporter::start(&plan, &scene, &state, "cpu").unwrap();
    state.positions[5][1] = f32::NAN;
    let e = exporter.record(&state).unwrap_err().to_string();
    assert!(e.contains("1 vertices that are NaN or infinite") && e.contains("raise the substeps"), "{e}");
    drop(exporter);
    assert!(names_in(&dir).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}
