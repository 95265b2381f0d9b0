//! The inspector runs without user input under Xvfb and its screenshot shows the cloth, on every
//! backend (not a blank or black frame).

use std::path::Path;
use std::process::Command;

fn has_xvfb() -> bool {
    Command::new("xvfb-run").arg("--help").output().is_ok()
}

/// Decodes an RGBA PNG to `(width, height, pixels)`.
fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The cloth's plain colour, shaded: clearly orange (red well above blue).
fn is_cloth(p: &[u8]) -> bool {
    let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
    r > 120 && r - b > 90 && g > 40 && g < r
}

/// The sphere's colour: grey-blue, blue above red.
fn is_sphere(p: &[u8]) -> bool {
    let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
    b > r + 5 && g > r && r > 25 && b < 200
}

#[test]
fn screenshot_shows_the_cloth_over_the_sphere_on_every_backend() {
    if !has_xvfb() {
        assert!(
            std::env::var_os("CI").is_none(),
            "xvfb-run is missing and CI is set: install xvfb (cargo xtask setup)"
        );
        eprintln!("SKIPPED: xvfb-run is not installed");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for backend in ["cpu", "wgpu", "vulkano"] {
        let out = std::env::temp_dir().join(format!("cloth-inspector-{backend}-{}.png", std::process::id()));
        let output = Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1280x800x24"])
            .arg(env!("CARGO_BIN_EXE_cloth-inspector"))
            .args(["--scene", "scenes/hold.ron", "--backend", backend, "--frames", "90", "--screenshot"])
            .arg(&out)
            .current_dir(&root)
            .output()
            .expect("xvfb-run starts");
        let log = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{backend}: the inspector exited with {}:\n{log}", output.status);
        // It ran where it was asked to, without falling back (the wgpu backend shares eframe's
        // device, which must be opened with the limits the simulator needs).
        assert!(log.contains(&format!("ran on the {backend} backend")), "{backend}: fell back:\n{log}");
        assert!(!log.contains("notice:"), "{backend}: the inspector reported a problem:\n{log}");
        let (w, h, pixels) = decode(&out);
        assert!(w >= 640 && h >= 400, "{backend}: {w}x{h}");
        let total = (w * h) as usize;
        let cloth = pixels.chunks_exact(4).filter(|p| is_cloth(p)).count();
        let sphere = pixels.chunks_exact(4).filter(|p| is_sphere(p)).count();
        let black = pixels.chunks_exact(4).filter(|p| p[0] < 8 && p[1] < 8 && p[2] < 8).count();
        eprintln!("{backend}: {cloth} cloth, {sphere} sphere, {black} black pixels of {total}");
        assert!(cloth > total / 100, "{backend}: only {cloth} cloth-coloured pixels of {total}");
        assert!(sphere > total / 200, "{backend}: only {sphere} sphere-coloured pixels of {total}");
        assert!(black < total / 2, "{backend}: the frame is mostly black");
        // The cloth lies over the sphere: the mean row of cloth pixels is above the sphere's.
        let mean_row = |f: fn(&[u8]) -> bool| {
            let rows: Vec<usize> =
                pixels.chunks_exact(4).enumerate().filter(|(_, p)| f(p)).map(|(i, _)| i / w as usize).collect();
            rows.iter().sum::<usize>() as f64 / rows.len().max(1) as f64
        };
        assert!(mean_row(is_cloth) < mean_row(is_sphere), "{backend}: the cloth is not above the sphere");
        let _ = std::fs::remove_file(out);
    }
}

/// `--measure-effects`: the stats panel's per-effect breakdown is measured in the background at
/// start, and a headless run waits for it and prints it: a row for the bare cloth and one for each
/// effect of the scene, with positive median times and added costs that are never negative.
#[test]
fn the_effect_cost_breakdown_is_measured_and_shown() {
    if !has_xvfb() {
        assert!(std::env::var_os("CI").is_none(), "xvfb-run is missing and CI is set");
        eprintln!("SKIPPED: xvfb-run is not installed");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = std::env::temp_dir().join(format!("cloth-inspector-costs-{}.png", std::process::id()));
    let output = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x800x24"])
        .arg(env!("CARGO_BIN_EXE_cloth-inspector"))
        .args(["--scene", "scenes/hold.ron", "--backend", "wgpu", "--frames", "5", "--measure-effects"])
        .arg("--screenshot")
        .arg(&out)
        .current_dir(&root)
        .output()
        .expect("xvfb-run starts");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "the inspector exited with {}:\n{log}", output.status);
    assert!(log.contains("effect costs on wgpu"), "no breakdown printed:\n{log}");
    let scene = cloth_core::Scene::load(&root.join("scenes/hold.ron")).expect("hold.ron loads");
    let rows: Vec<&str> = log.lines().filter(|l| l.contains("ms/frame")).collect();
    assert_eq!(rows.len(), 1 + scene.effects.iter().count(), "one row per effect and the bare cloth:\n{log}");
    assert!(rows[0].contains("bare cloth"), "{log}");
    for (row, effect) in rows[1..].iter().zip(scene.effects.iter()) {
        assert!(row.contains(&format!("{effect:?}")), "row for {effect:?}: {row}");
    }
    for row in &rows {
        let words: Vec<&str> = row.split_whitespace().collect();
        let at = words.iter().position(|w| *w == "ms/frame").expect("ms/frame");
        let ms: f64 = words[at - 1].parse().expect("a time before ms/frame");
        assert!(ms > 0.0 && ms.is_finite(), "{row}");
        // An added cost is a cost, a saving or inside the noise: never a negative number.
        let added = row.split("| ").nth(1).expect("an added column");
        assert!(!added.starts_with('-') && !added.starts_with("+-"), "{row}");
    }
    let _ = std::fs::remove_file(out);
}

/// A headless run that cannot do its work says so and exits non-zero before it opens a window:
/// a picture path it cannot write, a frame count beyond the work budget.
#[test]
fn a_headless_run_that_cannot_finish_is_refused_before_it_starts() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for (args, expected) in [
        (&["--frames", "2", "--screenshot", "/nonexistent/folder/x.png"][..], "cannot write /nonexistent/folder/x.png"),
        (&["--frames", "4294967295", "--screenshot", "x.png"][..], "--frames: 4294967295 frames is more than"),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_cloth-inspector"))
            .args(args)
            .env("RUST_BACKTRACE", "0")
            .current_dir(&root)
            .output()
            .expect("the inspector starts");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.starts_with("error: ") && stderr.contains(expected), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "one line, no backtrace: {stderr}");
    }
}
