//! The `cloth` binary as a user runs it.

use std::process::Command;

fn cloth(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(args)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .output()
        .expect("the cloth binary runs")
}

/// A CSV `cloth bench` wrote: each row's fields after the quoted adapter (the second column, which
/// may hold commas), and a column's index among those fields.
struct BenchCsv {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl BenchCsv {
    fn read(path: &std::path::Path) -> Self {
        let table = std::fs::read_to_string(path).expect("the CSV was written");
        let mut lines = table.lines();
        let header = lines.next().expect("a header").split(',').map(str::to_string).collect();
        let after_adapter =
            |r: &str| r.split_once("\",").expect("a quoted adapter").1.split(',').map(str::to_string).collect();
        Self { header, rows: lines.map(after_adapter).collect() }
    }

    /// Each row's fields as string slices.
    fn fields(&self) -> Vec<Vec<&str>> {
        self.rows.iter().map(|r| r.iter().map(String::as_str).collect()).collect()
    }

    fn at(&self, name: &str) -> usize {
        self.header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}")) - 2
    }
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = cloth(args);
    assert!(out.status.success(), "cloth {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn run_json_reports_every_documented_field() {
    let v = json(&["run", "scenes/drape.ron", "--frames", "20", "--grid", "7x13", "--json"]);
    for key in [
        "backend",
        "adapter",
        "vertices",
        "springs",
        "frames",
        "substeps_per_frame",
        "simulated_seconds",
        "max_penetration_m",
        "nan_count",
        "final_kinetic_energy_j",
        "final_centroid_m",
        "wall_ms_per_frame",
        "substeps_per_dispatch",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    assert_eq!(v["backend"], "cpu");
    assert_eq!(v["vertices"], 91, "--grid 7x13 gives 91 vertices");
    assert_eq!(v["springs"]["structural"], 7 * 12 + 13 * 6);
    assert_eq!(v["springs"]["shear"], 2 * 6 * 12);
    assert_eq!(v["springs"]["bend"], 7 * 11 + 13 * 5);
    assert_eq!(v["frames"], 20);
    assert_eq!(v["nan_count"], 0);
    assert_eq!(v["final_centroid_m"].as_array().unwrap().len(), 3);
    // Exactly the two counts, the maximum over every frame at least the final one.
    let crossings = v["self_intersections"].as_object().expect("self_intersections");
    assert_eq!(crossings.keys().collect::<Vec<_>>(), ["final", "max"]);
    assert!(crossings["max"].as_u64().unwrap() >= crossings["final"].as_u64().unwrap(), "{v}");
}

/// Decodes a PNG into RGBA pixels and its size.
fn decode_png(bytes: &[u8]) -> (Vec<u8>, u32, u32) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    pixels.truncate(info.buffer_size());
    (pixels, info.width, info.height)
}

/// `--png` draws with the inspector's renderer offscreen (lavapipe where there is no GPU; CI has
/// it, so a fallback fails this test): the sky, the ground grid's lines and the colliders are
/// there, and the shading is smooth (many shades of the cloth's colour).
#[test]
fn run_draws_a_png_with_the_inspectors_renderer() {
    let path = std::env::temp_dir().join(format!("cloth-cli-test-{}.png", std::process::id()));
    let args = ["run", "scenes/colliders.ron", "--frames", "5", "--grid", "16x16", "--png", path.to_str().unwrap()];
    let out = cloth(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("drawn by the inspector's renderer on "), "{stdout}");
    let (pixels, width, height) = decode_png(&std::fs::read(&path).unwrap());
    assert_eq!((width, height), (800, 600));
    let count = |rgb: [u8; 3]| pixels.chunks(4).filter(|p| p[..3] == rgb).count();
    // render.wgsl's sky (0.78, 0.82, 0.88) and grid lines (0.62, 0.64, 0.68), 8-bit.
    assert!(count([199, 209, 224]) > 10_000, "the sky");
    assert!(count([158, 163, 173]) > 200, "the ground grid");
    let shades: std::collections::HashSet<&[u8]> = pixels.chunks(4).map(|p| &p[..3]).collect();
    assert!(shades.len() > 200, "smooth shading gives many shades: {}", shades.len());
    let _ = std::fs::remove_file(path);
}

/// Without any Vulkan device (the loader pointed at no driver), `--png` falls back to the CPU
/// rasteriser and says so.
#[test]
fn without_a_vulkan_device_the_png_is_drawn_on_the_cpu_and_the_run_says_so() {
    let path = std::env::temp_dir().join(format!("cloth-cli-test-fallback-{}.png", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(["run", "--frames", "3", "--grid", "12x12", "--png", path.to_str().unwrap()])
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        stdout.contains("drawn by the CPU rasteriser (flat shading, no ground, plain colour: no Vulkan device"),
        "{stdout}"
    );
    let (_, width, height) = decode_png(&std::fs::read(&path).unwrap());
    assert_eq!((width, height), (800, 600));
    let _ = std::fs::remove_file(path);
}

/// `--gif` writes an animation of the run, and `--color` picks the cloth's colours.
#[test]
fn run_draws_an_animated_gif() {
    let path = std::env::temp_dir().join(format!("cloth-cli-test-{}.gif", std::process::id()));
    let args = ["run", "--frames", "6", "--grid", "12x12", "--color", "speed", "--gif", path.to_str().unwrap()];
    let out = cloth(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("(6 pictures, drawn by the inspector's renderer"), "{stdout}");
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..6], b"GIF89a");
    let _ = std::fs::remove_file(path);
}

/// `--export` writes a GLB (or a folder) and says so; a run too large for the format is refused
/// before it starts with the frames that fit; a run killed mid-export leaves no file under the
/// final name.
#[test]
fn run_exports_and_refuses_what_the_format_cannot_hold() {
    let dir = std::env::temp_dir().join(format!("cloth-cli-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let glb = dir.join("drape.glb");
    let out = cloth(&["run", "--frames", "6", "--grid", "10x10", "--export", glb.to_str().unwrap(), "--every", "3"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains(&format!("export      {} (3 frames, ", glb.display())), "{stdout}");
    assert_eq!(&std::fs::read(&glb).unwrap()[..4], b"glTF");
    // Read back and drawn by `cloth view`.
    let picture = dir.join("view.png");
    let out = cloth(&["view", glb.to_str().unwrap(), "--png", picture.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("frames      3 kept, t = 0.0000 to 0.1000 s"), "{stdout}");
    assert!(stdout.contains("frame       2 at t = 0.1000 s") && picture.is_file(), "{stdout}");
    let out = cloth(&["view", glb.to_str().unwrap(), "--frame", "3"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("--frame 3: the export keeps frames 0 to 2"));
    let folder = format!("{}/frames/", dir.display());
    let v = json(&["run", "--frames", "2", "--grid", "10x10", "--json", "--export", &folder]);
    assert_eq!((v["export"]["path"].as_str(), v["export"]["frames"].as_u64()), (Some(folder.as_str()), Some(3)), "{v}");
    assert!(dir.join("frames/diagnostics.csv").is_file() && dir.join("frames/frame_00002.obj").is_file());
    let big = dir.join("big.glb");
    let out = cloth(&[
        "run",
        "--grid",
        "1024x1024",
        "--frames",
        "300",
        "--backend",
        "wgpu",
        "--export",
        big.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("frames fit at --every 1"), "{stderr}");
    assert!(!big.exists());
    // Killed while it runs: only hidden temporary files may remain, never the final name.
    let killed = dir.join("killed.glb");
    let mut child = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(["run", "--frames", "2000", "--grid", "24x24", "--export", killed.to_str().unwrap()])
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!killed.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--obj` writes the final cloth as a Wavefront OBJ: a vertex and a normal per cloth vertex, two
/// triangles a cell, nothing else; the vertices are the final positions (the JSON's centroid).
/// `--count-every 0` counts the self-intersections of the final state only.
#[test]
fn run_writes_the_cloth_as_an_obj() {
    let path = std::env::temp_dir().join(format!("cloth-cli-test-{}.obj", std::process::id()));
    let args =
        ["run", "--frames", "10", "--grid", "9x7", "--json", "--count-every", "0", "--obj", path.to_str().unwrap()];
    let v = json(&args);
    // Counted on the final state only: the maximum is that count.
    assert_eq!(v["self_intersections"]["max"], v["self_intersections"]["final"], "{v}");
    let text = std::fs::read_to_string(&path).unwrap();
    let lines = |prefix: &str| text.lines().filter(|l| l.starts_with(prefix)).collect::<Vec<_>>();
    assert_eq!((lines("v ").len(), lines("vn ").len(), lines("f ").len()), (63, 63, 2 * 8 * 6));
    assert!(text.lines().all(|l| ["#", "v ", "vn ", "f "].iter().any(|p| l.starts_with(p))), "{text}");
    let mut centroid = [0.0f64; 3];
    for l in lines("v ") {
        for (c, x) in centroid.iter_mut().zip(l.split_whitespace().skip(1)) {
            *c += x.parse::<f64>().unwrap() / 63.0;
        }
    }
    for (k, c) in centroid.iter().enumerate() {
        assert!((c - v["final_centroid_m"][k].as_f64().unwrap()).abs() < 1e-5, "{centroid:?} {v}");
    }
    let _ = std::fs::remove_file(path);
}

#[test]
fn check_prints_counts_memory_and_the_bound() {
    let out = cloth(&["check", "scenes/drape.ron"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(text.contains("1984 structural, 1922 shear, 1920 bend"), "{text}");
    assert!(text.contains("largest stable substep"), "{text}");
    assert!(text.contains("MiB on the device"), "{text}");
}

#[test]
fn check_says_when_every_self_collision_check_would_rebuild() {
    let out = cloth(&["check", "scenes/self_collision_bench.ron"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("checked every 4 substep(s)"), "{text}");
    assert!(!text.contains("every check rebuilds"), "{text}");
    // RK4's stages reach one substep past the check: with a margin of 0.1 mm that lookahead,
    // 2 s_max Δt = 1.56 mm, takes the whole margin.
    let scene =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/self_collision_bench.ron")).unwrap();
    let thin = scene
        .replace("margin: Spacings(1.5)", "margin: Meters(1e-4)")
        .replace("    air_drag: 0.2,", "    air_drag: 0.2,\n    integrator: RungeKutta4,");
    assert_ne!(thin, scene);
    let path = std::env::temp_dir().join(format!("cloth-cli-thin-margin-{}.ron", std::process::id()));
    std::fs::write(&path, thin).unwrap();
    let out = cloth(&["check", path.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("every check rebuilds the lists") && text.contains("above 1.563e-3 m"), "{text}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn bad_input_gives_a_clear_message_and_no_panic() {
    let out = cloth(&["run", "--grid", "1x5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("cloth.resolution[0]: is 1 vertices"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let out = cloth(&["run", "--grid", "12by5"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not NXxNY"));
    let out = cloth(&["run", "--backend", "nonesuch"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown backend 'nonesuch'"));
    let out = cloth(&["check", "no/such/file.ron"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read scene file no/such/file.ron"));
}

#[test]
fn backends_lists_the_cpu_reference() {
    let out = cloth(&["backends"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("cpu ") && text.contains("cpu-f64"), "{text}");
    assert!(text.contains("wgpu ") && text.contains("vulkano "), "{text}");
}

#[test]
fn run_on_the_gpu_backends_drapes_without_nan_or_deep_penetration() {
    for backend in ["wgpu", "vulkano"] {
        run_on_gpu(backend);
    }
}

fn run_on_gpu(backend: &str) {
    let out = cloth(&["run", "--backend", backend, "scenes/drape.ron", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() && stderr.contains("unavailable") && std::env::var_os("CI").is_none() {
        eprintln!("SKIPPED: no {backend} adapter here: {stderr}");
        return;
    }
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["backend"], backend);
    assert_eq!(v["nan_count"], 0);
    assert!(v["max_penetration_fraction_of_radius"].as_f64().unwrap() < 0.02, "{v}");
    assert_eq!(v["submissions_per_frame"], 1.0);
    assert_eq!(v["host_waits_per_frame"], 0.0);
    // The drape (32², semi-implicit Euler) runs the tiled kernel on a GPU, two substeps per
    // dispatch, and one substep per dispatch on a CPU implementation (lavapipe), where it is slower.
    let expected = if v["adapter"].as_str().unwrap().contains("Cpu") { 1 } else { 2 };
    assert_eq!(v["substeps_per_dispatch"], expected, "{v}");
}

#[test]
fn study_accuracy_writes_csv_plot_and_report_where_higher_order_is_more_accurate() {
    let dir = std::env::temp_dir().join(format!("cloth-study-{}", std::process::id()));
    let (csv, report) = (dir.join("accuracy.csv"), dir.join("report").join("accuracy.md"));
    std::fs::create_dir_all(report.parent().unwrap()).unwrap();
    let out = cloth(&[
        "study",
        "accuracy",
        "scenes/hanging.ron",
        "--grid",
        "6x6",
        "--duration",
        "0.1",
        "--substeps",
        "16,32",
        // The four integrators with a theoretical order (the implicit ones cost this test's
        // lavapipe time three times over and add nothing to what it checks).
        "--integrators",
        "euler,verlet,rk4,xpbd",
        "--backends",
        "cpu-f64,wgpu",
        "--csv",
        csv.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let wgpu_ran = rows.iter().any(|r| r[0] == "wgpu");
    if !wgpu_ran && std::env::var_os("CI").is_none() {
        eprintln!("SKIPPED the wgpu half: no adapter here ({stderr})");
    }
    let backends: &[&str] = if wgpu_ran { &["cpu-f64", "wgpu"] } else { &["cpu-f64"] };
    assert_eq!(rows.len(), backends.len() * 4 * 2, "backends x 4 integrators x 2 substep counts:\n{text}");
    for backend in backends {
        let error = |method: &str, n: &str| -> f64 {
            let row = rows.iter().find(|r| r[0] == *backend && r[1] == method && r[2] == n).unwrap();
            row[column("rms_error_m")].parse().unwrap()
        };
        for n in ["16", "32"] {
            assert!(
                error("rk4", n) < error("verlet", n) && error("verlet", n) < error("euler", n),
                "{backend} at {n} substeps:\n{text}"
            );
        }
    }
    // The GPU rows are costed with GPU timestamps (lavapipe has them), the CPU rows by the clock.
    for r in &rows {
        let expected = if r[0] == "wgpu" { "gpu" } else { "wall" };
        assert_eq!(r[column("cost_clock")], expected, "{r:?}");
        assert!(r[column("cost_ms_per_simulated_s")].parse::<f64>().unwrap() > 0.0, "{r:?}");
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("largest stable substep"), "{stdout}");
    let png = std::fs::read(csv.with_extension("png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "the plot is a PNG");
    assert!(std::fs::read_to_string(csv.with_extension("svg")).unwrap().contains("<svg"));
    let md = std::fs::read_to_string(&report).unwrap();
    for section in [
        "## Which integrator and step, for an error budget and a frame-time budget",
        "## Largest step with a bounded error",
        "## Which integrator for an error budget alone",
        "## Measured order of accuracy",
        "## Largest stable step",
        "## Every run",
    ] {
        assert!(md.contains(section), "the report has {section}:\n{md}");
    }
    assert!(md.contains("![") && md.contains("(accuracy.png)"), "the report shows its plot");
    for copied in ["accuracy.png", "accuracy.svg", "accuracy.csv"] {
        assert!(report.parent().unwrap().join(copied).exists(), "{copied} beside the report");
    }
    assert!(md.contains("study accuracy scenes/hanging.ron --grid 6x6"), "the report names the command that made it");
    let _ = std::fs::remove_dir_all(dir);
}

/// The study's default scenes (the hanging cloth, the drape, the stiff drape) at 4 × 4 on the f64
/// CPU: one CSV with a scene column, the explicit integrator diverging at one substep a frame on
/// the stiff drape where backward Euler and VBD stay finite and report their iterations, and the
/// report's per-scene two-budget tables with their generated discussion.
#[test]
fn study_accuracy_compares_the_default_scenes_and_the_implicit_integrators() {
    let dir = std::env::temp_dir().join(format!("cloth-study-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, report) = (dir.join("accuracy.csv"), dir.join("accuracy.md"));
    let out = cloth(&[
        "study",
        "accuracy",
        "--grid",
        "4x4",
        "--duration",
        "0.1",
        "--substeps",
        "1,8",
        "--integrators",
        "euler,xpbd,backward-euler,vbd",
        "--backends",
        "cpu-f64",
        "--no-bisection",
        "--frame-budgets",
        "0.5,100",
        "--csv",
        csv.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 3 * 4 * 2, "3 scenes x 4 integrators x 2 substep counts:\n{text}");
    let row = |scene: &str, method: &str, n: &str| {
        rows.iter()
            .find(|r| r[column("scene")] == scene && r[1] == method && r[2] == n)
            .unwrap_or_else(|| panic!("no {scene} {method} {n}:\n{text}"))
    };
    assert_eq!(row("stiff drape", "euler", "1")[column("diverged")], "true", "{text}");
    for method in ["backward-euler", "vbd"] {
        let r = row("stiff drape", method, "1");
        assert_eq!(r[column("diverged")], "false", "{method}: {r:?}");
        let iterations: f64 = r[column("solver_iterations_per_substep")].parse().unwrap();
        assert!(iterations >= 1.0, "{method} spends its solver's iterations: {r:?}");
        let dissipated: f64 = r[column("energy_dissipated_j")].parse().unwrap();
        assert!(dissipated.is_finite(), "{r:?}");
    }
    assert_eq!(row("drape", "euler", "8")[column("solver_iterations_per_substep")], "", "explicit: no solver");
    let md = std::fs::read_to_string(&report).unwrap();
    for scene in ["### hanging", "### drape", "### stiff drape"] {
        assert!(
            md.matches(scene).count() >= 3,
            "{scene} has its two-budget, bounded-step and one-substep tables:\n{md}"
        );
    }
    assert!(md.contains("≤ 0.5 ms / frame") && md.contains("≤ 100 ms / frame"), "the frame budgets asked for");
    assert!(md.contains("Within 1e-2 m the largest step is"), "the discussion is generated:\n{md}");
    assert!(md.contains("At 1 substep a frame euler diverges."), "the stiff drape's divergence is said:\n{md}");
    let _ = std::fs::remove_dir_all(dir);
}

/// `cloth bench` on the CPU and both GPU backends: a row per backend, grid and step rule in the
/// CSV, GPU rows timed by timestamps with a ceiling fraction against the measured copy bandwidth,
/// one submission per frame, every row finite.
#[test]
fn bench_writes_a_row_per_backend_grid_and_step_with_gpu_time_and_ceiling() {
    let csv = std::env::temp_dir().join(format!("cloth-bench-{}.csv", std::process::id()));
    let out = cloth(&[
        "bench",
        "--backends",
        "cpu,wgpu,vulkano",
        "--grids",
        "8,12",
        "--substeps",
        "4,scaled",
        "--frames",
        "2",
        "--repeats",
        "3",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "bench failed: {text}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("device copy bandwidth:") && text.contains("ceiling at 64 bytes"), "{text}");
    let table = std::fs::read_to_string(&csv).expect("the CSV was written");
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<String>> = lines
        .map(|l| {
            // The adapter is the one quoted field (and may hold commas).
            let (before, rest) = l.split_once(",\"").unwrap();
            let (adapter, after) = rest.split_once("\",").unwrap();
            let mut fields = vec![before.to_string(), adapter.to_string()];
            fields.extend(after.split(',').map(str::to_string));
            fields
        })
        .collect();
    assert_eq!(rows.len(), 3 * 2 * 2, "{table}");
    for r in &rows {
        assert_eq!(r[column("finite")], "true", "{r:?}");
        let gpu = !r[0].starts_with("cpu");
        assert_eq!(r[column("gpu_ms_per_frame")].is_empty(), !gpu, "{r:?}");
        assert_eq!(r[column("ceiling_fraction")].is_empty(), !gpu, "{r:?}");
        // Each row's times are medians of three timings, with their spread.
        assert_eq!(r[column("repeats")], "3", "{r:?}");
        assert_eq!(r[column("gpu_ms_spread")].is_empty(), !gpu, "{r:?}");
        let spread: f64 = r[column("wall_ms_spread")].parse().unwrap();
        assert!(spread >= 0.0 && spread.is_finite(), "{r:?}");
        // Tiles on a GPU; not on the CPU reference or a CPU implementation of Vulkan.
        let fused = if gpu && !r[column("adapter")].contains("Cpu") { "2" } else { "1" };
        assert_eq!(r[column("fused_substeps")], fused, "{r:?}");
        // Untiled, the GPU backends run Euler on its packed state (24 bytes a vertex).
        let state = match (gpu, fused) {
            (false, _) => "",
            (true, "1") => "24",
            _ => "32",
        };
        assert_eq!(r[column("state_bytes_per_vertex")], state, "{r:?}");
        if gpu {
            assert_eq!(r[column("submissions_per_frame")], "1.000", "{r:?}");
            let fraction: f64 = r[column("ceiling_fraction")].parse().unwrap();
            assert!(fraction > 0.0 && fraction < 1.0, "{r:?}");
        }
    }
    // The scaled step: round(frame_dt · n / 0.04) substeps, 3 at n = 8 and 5 at n = 12.
    let scaled: Vec<&str> =
        rows.iter().filter(|r| r[column("step_rule")] == "scaled").map(|r| r[column("substeps")].as_str()).collect();
    assert_eq!(scaled, ["3", "5", "3", "5", "3", "5"]);
    let _ = std::fs::remove_file(csv);
}

/// `cloth bench --effects` times each row repeatedly and says of each added effect whether it
/// costs, saves, or is inside the noise: never a bare negative cost. Fewer than three timings
/// are refused, naming the flag.
/// `cloth profile` on a GPU backend: a row a pass, the substeps' and self-collision's, with the
/// frame's dispatches in the table and the CSV; the CPU backends are refused.
#[test]
fn profile_prints_and_writes_each_pass_of_a_gpu_frame() {
    let csv = std::env::temp_dir().join(format!("cloth-profile-{}.csv", std::process::id()));
    let out = cloth(&[
        "profile",
        "scenes/self_collision_bench.ron",
        "--backend",
        "vulkano",
        "--grid",
        "12x12",
        "--frames",
        "2",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "profile failed: {text}\n{}", String::from_utf8_lossy(&out.stderr));
    for pass in ["Euler substep", "self-collision forced check", "self-collision check", "self-collision insert"] {
        assert!(text.lines().any(|l| l.starts_with(pass)), "no row {pass}:\n{text}");
    }
    assert!(text.contains("checks rebuilt the lists"), "{text}");
    let table = std::fs::read_to_string(&csv).expect("the CSV was written");
    let _ = std::fs::remove_file(&csv);
    let step: Vec<f64> = (table.lines().find(|l| l.contains(",\"Euler substep\",")).expect("the substeps' row"))
        .rsplit(',')
        .take(5)
        .map(|f| f.parse().unwrap())
        .collect();
    // From the end: the longest and shortest dispatch and the mean, µs, the ms a frame, and the
    // dispatches a frame, 64 (one a substep).
    let [longest, shortest, mean, ms, dispatches] = step[..] else { unreachable!() };
    assert_eq!(dispatches, 64.0, "{table}");
    assert!(ms > 0.0 && 0.0 < shortest && shortest <= mean && mean <= longest, "{table}");
    let refused = cloth(&["profile", "--backend", "cpu"]);
    assert_eq!(refused.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("profile wgpu or vulkano"));
}

#[test]
fn effect_costs_are_medians_with_a_verdict_on_the_noise() {
    let out = cloth(&["bench", "--effects", "--backends", "cpu", "--grids", "16", "--repeats", "2"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--repeats 2 is too few"), "{stderr}");
    let csv = std::env::temp_dir().join(format!("cloth-effects-{}.csv", std::process::id()));
    let out = cloth(&[
        "bench",
        "--effects",
        "--backends",
        "cpu",
        "--grids",
        "16",
        "--frames",
        "1",
        "--repeats",
        "3",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let table = BenchCsv::read(&csv);
    let at = |name: &str| table.at(name);
    let scene = cloth_core::Scene::from_ron_str(include_str!("../../../scenes/flag.ron")).unwrap();
    let rows = table.fields();
    // The bare row, one per effect, and one per collider kind after the first (Contact's).
    let kinds: std::collections::BTreeSet<_> = scene.colliders.iter().map(|c| c.kind()).collect();
    assert_eq!(rows.len(), 1 + scene.effects.iter().count() + kinds.len() - 1, "{rows:?}");
    let labels: Vec<&str> = rows.iter().map(|r| r[at("row")]).collect();
    assert!(labels.contains(&"+ Contact (sphere)"), "{labels:?}");
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[at("repeats")], "3", "{r:?}");
        let (verdict, added, low, high) =
            (r[at("added")], r[at("added_ms")], r[at("added_low_ms")], r[at("added_high_ms")]);
        if k == 0 {
            assert_eq!([verdict, added, low, high], ["", "", "", ""], "the bare row adds nothing: {r:?}");
            continue;
        }
        let (low, high): (f64, f64) = (low.parse().unwrap(), high.parse().unwrap());
        match verdict {
            "costs" => assert!(low > 0.0 && added.parse::<f64>().unwrap() > 0.0, "{r:?}"),
            "saves" => assert!(high < 0.0 && added.parse::<f64>().unwrap() < 0.0, "{r:?}"),
            "inside_noise" => assert!(low <= 0.0 && high >= 0.0 && added.is_empty(), "{r:?}"),
            other => panic!("verdict {other}: {r:?}"),
        }
    }
    for line in stdout.lines().filter(|l| l.trim_start().starts_with('+')) {
        let added = line.split_whitespace().skip(4).collect::<Vec<_>>().join(" ");
        assert!(!added.starts_with('-') && !added.starts_with("+-"), "a negative cost printed: {line}");
    }
    let _ = std::fs::remove_file(csv);
}

/// With `SelfCollision` on a GPU backend, `cloth bench --effects` reports how its candidate lists
/// fared over the timed frames, in the CSV's last columns: on the row that adds the effect, checks
/// (at least one a frame) and no more rebuilds than checks; empty on the rows without it.
#[test]
fn effect_costs_report_self_collisions_candidate_lists() {
    let csv = std::env::temp_dir().join(format!("cloth-effects-lists-{}.csv", std::process::id()));
    let flags = "bench --effects --scene scenes/self_collision_bench.ron --backends vulkano --grids 16 --frames 2";
    let mut args: Vec<&str> = flags.split(' ').chain(["--repeats", "3", "--csv"]).collect();
    args.push(csv.to_str().unwrap());
    let out = cloth(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    if stdout.contains("skipped") && std::env::var_os("CI").is_none() {
        eprintln!("SKIPPED: no GPU adapter here: {stdout}");
        return;
    }
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("self-collision's candidate lists over the 6 timed frames"), "{stdout}");
    let table = BenchCsv::read(&csv);
    let at = |name: &str| table.at(name);
    for r in table.fields() {
        let row = r.join(",");
        let lists = [r[at("checks")], r[at("rebuilds")], r[at("overflowed_lists")]];
        if !r[at("effects")].contains("SelfCollision") {
            assert_eq!(lists, ["", "", ""], "no lists without the effect: {row}");
            continue;
        }
        assert_eq!(r[at("timed_frames")], "6", "{row}");
        let [checks, rebuilds, _]: [u64; 3] = lists.map(|v| v.parse().unwrap_or_else(|_| panic!("{v:?}: {row}")));
        assert!(checks >= 6 && rebuilds <= checks, "{row}");
    }
    let _ = std::fs::remove_file(csv);
}

/// `cloth bench`'s GPU tuning flags reach the backends: `--tiling on|off` chooses the tiled kernel
/// for semi-implicit Euler on every GPU backend, whatever the device (lavapipe does not tile by
/// default), and `--packed-state off` keeps the two `vec4`s: the CSV's fused substeps and state.
#[test]
fn bench_tuning_flags_choose_the_kernels() {
    for (flags, fused, state) in
        [(["--tiling", "on"], "2", "32"), (["--tiling", "off"], "1", "24"), (["--packed-state", "off"], "1", "32")]
    {
        let csv =
            std::env::temp_dir().join(format!("cloth-bench-{}-{}-{}.csv", flags[0], flags[1], std::process::id()));
        let mut args = vec![
            "bench",
            "--backends",
            "wgpu,vulkano",
            "--grids",
            "40",
            "--substeps",
            "4",
            "--frames",
            "1",
            "--repeats",
            "1",
        ];
        args.extend(flags);
        args.extend(["--csv", csv.to_str().unwrap()]);
        let out = cloth(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        if stdout.contains("skipped") && std::env::var_os("CI").is_none() {
            eprintln!("SKIPPED: no GPU adapter here: {stdout}");
            return;
        }
        let table = BenchCsv::read(&csv);
        let rows = table.fields();
        assert_eq!(rows.len(), 2, "{rows:?}");
        for row in rows {
            assert_eq!(row[table.at("fused_substeps")], fused, "{flags:?}: {row:?}");
            assert_eq!(row[table.at("state_bytes_per_vertex")], state, "{flags:?}: {row:?}");
        }
        let _ = std::fs::remove_file(csv);
    }
}

/// A GPU tuning value the kernels cannot run is refused with the field's name; a malformed flag
/// names the flag.
#[test]
fn a_wrong_tuning_flag_is_refused_naming_it() {
    let out = cloth(&["run", "--backend", "wgpu", "--frames", "1", "--workgroup-size", "48"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    if !stderr.contains("unavailable") {
        assert!(stderr.contains("GpuTuning::workgroup_size = 48"), "{stderr}");
    }
    let out = cloth(&["bench", "--tile", "32x16"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--tile") && stderr.contains("WIDTHxHEIGHTxSUBSTEPS"), "{stderr}");
}

/// A successful run prints nothing on standard error, on every backend, also on a machine
/// without a display session (no `XDG_RUNTIME_DIR`, where Mesa would complain).
#[test]
fn a_successful_run_is_quiet_on_stderr_on_every_backend() {
    for backend in ["cpu", "cpu-f64", "wgpu", "vulkano"] {
        let out = Command::new(env!("CARGO_BIN_EXE_cloth"))
            .args(["run", "--backend", backend, "--frames", "3", "--grid", "8x8"])
            .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
            .env_remove("XDG_RUNTIME_DIR")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        if !out.status.success() && stderr.contains("unavailable") && std::env::var_os("CI").is_none() {
            eprintln!("SKIPPED {backend}: {stderr}");
            continue;
        }
        assert!(out.status.success(), "{backend}: {stderr}");
        assert!(stderr.is_empty(), "{backend} printed on stderr: {stderr}");
    }
}

/// Output errors end the command with a message and a non-zero code, never a panic; a closed
/// pipe (`cloth ... | head`) ends it quietly, as Unix tools end.
#[test]
fn output_errors_end_the_command_without_a_panic() {
    let full = std::fs::File::create("/dev/full").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cloth")).arg("backends").stdout(full).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot write to standard output") && !stderr.contains("panicked"), "{stderr}");
    let mut child = Command::new(env!("CARGO_BIN_EXE_cloth"))
        .args(["bench", "--backends", "cpu", "--grids", "16,24,32", "--substeps", "4", "--frames", "1"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("error"), "{stderr}");
}

/// A command that produced no result says so and exits non-zero; a flag it would have adjusted is
/// refused (a flag that cannot be parsed: 2, the usual code of a usage error); `cloth check` exits
/// 3 for a valid scene whose substep exceeds the stable bound.
#[test]
fn exit_codes_say_whether_there_is_a_result() {
    let out = cloth(&["bench", "--backends", "cpu", "--grids", "1", "--substeps", "4", "--frames", "1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("no row was measured"), "{stderr}");
    for args in [&["bench", "--frames", "0"][..], &["run", "--frames", "0"]] {
        let out = cloth(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.code() == Some(2) && stderr.contains("--frames"), "{args:?}: {stderr}");
    }
    let out = cloth(&["check", "scenes/drape.ron", "--substeps", "1"]);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(3), "{stdout}{stderr}");
    assert!(stdout.contains("UNSTABLE") && stderr.contains("unstable: the substep is"), "{stdout}{stderr}");
    assert_eq!(cloth(&["check", "scenes/drape.ron"]).status.code(), Some(0));
}

/// A CPU accuracy study of a 4×4 cloth for 0.02 s, writing `csv`.
fn tiny_study(csv: &std::path::Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["study", "accuracy", "--grid", "4x4", "--duration", "0.02", "--substeps", "4"];
    args.extend(["--backends", "cpu", "--csv", csv.to_str().unwrap()]);
    args.extend(extra);
    cloth(&args)
}

/// Outputs are checked before the run starts, and written whole or not at all.
#[test]
fn outputs_are_checked_first_and_never_left_half_written() {
    let out = cloth(&["run", "--frames", "100000", "--png", "no/such/folder/x.png"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("cannot write no/such/folder/x.png"), "{stderr}");
    // A study whose output name is claimed by another run in the same folder is refused.
    let dir = std::env::temp_dir().join(format!("cloth-outputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("accuracy.csv");
    std::fs::write(dir.join("accuracy.csv.lock"), "").unwrap();
    let out = tiny_study(&csv, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("another run is writing"), "{stderr}");
    std::fs::remove_file(dir.join("accuracy.csv.lock")).unwrap();
    // A CSV whose final name is a folder: refused before the run, nothing left behind.
    std::fs::create_dir_all(dir.join("taken.csv")).unwrap();
    let out = cloth(&[
        "bench",
        "--backends",
        "cpu",
        "--grids",
        "8",
        "--substeps",
        "2",
        "--frames",
        "1",
        "--csv",
        dir.join("taken.csv").to_str().unwrap(),
    ]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("it is a folder"));
    // A study that succeeds leaves its files and no temporary or lock file.
    let out = tiny_study(&csv, &["--no-bisection"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["accuracy.csv", "accuracy.png", "accuracy.svg", "taken.csv"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `cloth run --integrator` takes the implicit integrators by their short names, and the report
/// says what their solvers spent: backward Euler's Newton and CG iterations, VBD's sweeps (the
/// scene's default 10 a substep).
#[test]
fn run_reports_what_the_implicit_solvers_spent() {
    for name in ["backward-euler", "vbd"] {
        let v = json(&["run", "--integrator", name, "--grid", "8x8", "--substeps", "4", "--frames", "3", "--json"]);
        assert_eq!(v["integrator"], name);
        let spent = &v["solver_iterations"];
        assert_eq!(spent["substeps"], 12, "{name}: {spent}");
        if name == "vbd" {
            assert_eq!(spent["vbd"], 120, "{name}: {spent}");
        } else {
            assert_eq!(spent["newton"], 24, "{name}: the default two Newton iterations a substep: {spent}");
            let cg = spent["cg"].as_u64().unwrap();
            assert!((24..=24 * 50).contains(&cg), "{name}: {spent}");
        }
    }
    let out = cloth(&["run", "--integrator", "implicit-euler", "--frames", "1"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("backward-euler") && stderr.contains("vbd"), "the error lists the names: {stderr}");
    let plain = json(&["run", "--grid", "8x8", "--frames", "1", "--json"]);
    assert!(plain["solver_iterations"].is_null(), "semi-implicit Euler has no solver");
}

/// `cloth study accuracy --solver` sets the implicit integrators' iterations for every scene (the
/// CSV's iterations a substep are the VBD sweeps asked for), and an invalid setting is refused
/// with the field named.
#[test]
fn study_accuracy_takes_the_solver_for_every_scene() {
    let dir = std::env::temp_dir().join(format!("cloth-study-solver-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("accuracy.csv");
    let study = |solver: &str| {
        cloth(&[
            "study",
            "accuracy",
            "scenes/hanging.ron",
            "--grid",
            "4x4",
            "--duration",
            "0.05",
            "--substeps",
            "1",
            "--integrators",
            "vbd",
            "--backends",
            "cpu",
            "--no-bisection",
            "--solver",
            solver,
            "--csv",
            csv.to_str().unwrap(),
        ])
    };
    let out = study("(vbd_iterations: 3, chebyshev_rho: 0.5)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = header.iter().position(|c| *c == "solver_iterations_per_substep").expect("the iterations column");
    let row: Vec<&str> = lines.next().expect("one run").split(',').collect();
    assert_eq!(row[column].parse::<f64>().unwrap(), 3.0, "{text}");
    let refused = study("(chebyshev_rho: 1.5)");
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(stderr.contains("chebyshev_rho"), "the error names the field: {stderr}");
    std::fs::remove_dir_all(&dir).ok();
}
