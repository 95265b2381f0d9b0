//! Loading scenes: the shipped files, malformed text, and random input (no panic, ever).

use cloth_core::{Scene, SceneError};
use proptest::prelude::*;

#[test]
fn shipped_scenes_load_and_drape_is_the_default() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for name in ["drape", "hanging", "slide", "hold", "floor", "table", "capsule", "heap", "mesh"] {
        let scene = Scene::load(&dir.join(format!("{name}.ron"))).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(scene.name, name);
        assert_eq!(scene.validate().unwrap(), vec![], "{name} has warnings");
    }
    assert_eq!(Scene::load(&dir.join("drape.ron")).unwrap(), Scene::default(), "drape.ron is Scene::default()");
}

#[test]
fn spheres_and_colliders_lists_both_load_as_colliders() {
    use cloth_core::colliders::{ColliderKind, Shape};
    // Neither list: the default sphere. Either: exactly what it lists, spheres first.
    assert_eq!(Scene::from_ron_str("Scene()").unwrap().colliders, Scene::default().colliders);
    let only_colliders = Scene::from_ron_str("Scene(colliders: [(shape: Plane())])").unwrap();
    assert_eq!(only_colliders.colliders.len(), 1, "no default sphere beside the listed colliders");
    assert_eq!(only_colliders.colliders[0].shape, Shape::Plane { normal: [0.0, 1.0, 0.0], offset: 0.0 });
    let none = Scene::from_ron_str("Scene(spheres: [])").unwrap();
    assert!(none.colliders.is_empty());
    let both = Scene::from_ron_str(
        "Scene(spheres: [(radius: 0.3)], colliders: [(shape: Capsule(a: (0, 0, 0), b: (1, 0, 0), radius: 0.1)), \
         (shape: Box(center: (0, 0, 0), half_extents: (1, 1, 1)), friction: 0.9)])",
    )
    .unwrap();
    let kinds: Vec<ColliderKind> = both.colliders.iter().map(|c| c.kind()).collect();
    assert_eq!(kinds, [ColliderKind::Sphere, ColliderKind::Capsule, ColliderKind::Box]);
    assert_eq!(both.colliders[2].friction, 0.9);
    // The old effect names still read.
    let old = Scene::from_ron_str("Scene(effects: [Gravity, SphereContact, MovingSpheres])").unwrap();
    assert!(
        old.effects.contains(cloth_core::Effect::Contact) && old.effects.contains(cloth_core::Effect::MovingColliders)
    );
    // And a scene with colliders round-trips (written as one colliders list).
    assert_eq!(Scene::from_ron_str(&both.to_ron_string()).unwrap(), both);
}

#[test]
fn degenerate_colliders_are_refused_by_field() {
    let cases = [
        ("Scene(colliders: [(shape: Plane(normal: (0, 0, 0)))])", "colliders[0].shape.Plane.normal: is (0, 0, 0)"),
        (
            "Scene(colliders: [(shape: Capsule(a: (0, 1, 0), b: (0, 1, 0), radius: 0.1))])",
            "colliders[0].shape.Capsule.b: equals a",
        ),
        (
            "Scene(colliders: [(shape: Capsule(a: (0, 1, 0), b: (1, 1, 0), radius: 0.0))])",
            "colliders[0].shape.Capsule.radius: is 0 m, must be greater than 0",
        ),
        (
            "Scene(colliders: [(shape: Box(center: (0, 0, 0), half_extents: (1, 0, 1)))])",
            "colliders[0].shape.Box.half_extents[1]: is 0 m, must be greater than 0",
        ),
        (
            "Scene(colliders: [(shape: Box(center: (0, 0, 0), half_extents: (1, -2, 1)))])",
            "colliders[0].shape.Box.half_extents[1]: is -2 m, must be greater than 0",
        ),
        (
            "Scene(colliders: [(shape: Box(center: (0, 0, 0), half_extents: (1, 0.5, 1), rounding: 0.6))])",
            "colliders[0].shape.Box.rounding: is 0.6 m, more than the smallest half extent, 0.5 m",
        ),
        (
            "Scene(colliders: [(shape: Box(center: (0, 0, 0), half_extents: (1, 1, 1), axis: (0, 0, 0), angle: 30))])",
            "colliders[0].shape.Box.axis: is (0, 0, 0)",
        ),
        (
            "Scene(colliders: [(shape: Sphere(center: (0, 1, 0), radius: 0.5), stiffness: -1)])",
            "colliders[0].stiffness",
        ),
        ("Scene(colliders: [(shape: Torus())])", "Torus"),
        ("Scene(cloth: (ripple: (amplitude: 0.1, wavelength: 0)))", "cloth.ripple.wavelength: is 0 m"),
        (
            "Scene(colliders: [(shape: Mesh(file: \"no/such/mesh.obj\"))])",
            "colliders[0].shape.Mesh.file: no/such/mesh.obj: cannot read it",
        ),
        (
            "Scene(colliders: [(shape: Mesh(file: \"scenes/meshes/torus.obj\", cells: 1))])",
            "colliders[0].shape.Mesh.cells: is 1",
        ),
        (
            "Scene(colliders: [(shape: Mesh(file: \"scenes/meshes/torus.obj\", scale: 0))])",
            "colliders[0].shape.Mesh.scale: is 0",
        ),
    ];
    for (text, expected) in cases {
        let err = Scene::from_ron_str(text).unwrap_err().to_string();
        assert!(err.contains(expected), "{text}\n  gave: {err}\n  expected: {expected}");
    }
}

/// A mesh file that is open, or has a bad line, is refused naming the field, the file and its
/// line; a relative path is read relative to the scene file.
#[test]
fn mesh_files_are_read_relative_to_the_scene_and_checked() {
    let dir = std::env::temp_dir().join(format!("cloth-mesh-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    // A tetrahedron missing a face, and one with a bad index on line 5.
    write("open.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n");
    write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 9\n");
    write("tet.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n");
    let scene = |file: &str| format!("Scene(colliders: [(shape: Mesh(file: \"{file}\", cells: 8))])");
    for (file, expected) in [
        ("open.obj", "open.obj:5: the mesh is not closed"),
        ("bad.obj", "bad.obj:5: vertex 9 does not exist (4 vertices so far)"),
    ] {
        write("scene.ron", &scene(file));
        let e = Scene::load(&dir.join("scene.ron")).unwrap_err().to_string();
        assert!(e.contains("colliders[0].shape.Mesh.file") && e.contains(expected), "{file}: {e}");
    }
    write("scene.ron", &scene("tet.obj"));
    let tet = Scene::load(&dir.join("scene.ron")).unwrap();
    let field = tet.colliders[0].shape.distance_field().unwrap().unwrap();
    assert_eq!(field.mesh.triangles.len(), 4);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_scene_round_trips_through_ron() {
    let scene = Scene::default();
    assert_eq!(Scene::from_ron_str(&scene.to_ron_string()).unwrap(), scene);
}

#[test]
fn malformed_text_reports_line_and_column() {
    let text = "Scene(\n  name: \"x\",\n  cloth: (resolution: (4, 4),,\n)";
    match Scene::from_ron_str(text) {
        Err(SceneError::Parse { line, column, .. }) => assert_eq!((line, column), (3, 30)),
        other => panic!("expected a parse error, got {other:?}"),
    }
    let err = Scene::from_ron_str("Scene(clth: ())").unwrap_err().to_string();
    assert!(err.contains("line 1") && err.contains("clth"), "unknown field is named: {err}");
}

#[test]
fn nan_and_infinity_in_a_file_are_reported_by_field() {
    let err = Scene::from_ron_str("Scene(gravity: (0.0, NaN, 0.0), air_drag: inf)").unwrap_err();
    let fields: Vec<_> = err.problems().iter().map(|p| p.field.as_str()).collect();
    assert_eq!(fields, ["gravity[1]", "air_drag"]);
    assert!(err.to_string().contains("gravity[1]: is NaN, not a finite number"), "{err}");
}

#[test]
fn each_bad_input_gives_its_message() {
    let cases = [
        ("Scene(cloth: (resolution: (1, 8)))", "cloth.resolution[0]: is 1 vertices; a cloth needs at least 2"),
        ("Scene(cloth: (resolution: (0, 0)))", "cloth.resolution[1]: is 0 vertices"),
        ("Scene(cloth: (mass: PerVertex(-0.1)))", "cloth.mass.PerVertex: is -0.1 kg, must be greater than 0"),
        ("Scene(spheres: [(radius: 0.0)])", "colliders[0].shape.Sphere.radius: is 0 m, must be greater than 0"),
        ("Scene(time: (frame_dt: -0.01))", "time.frame_dt: is -0.01 s, must be greater than 0"),
        (
            "Scene(springs: (bend: (stiffness: -1.0, damping: 0.0)))",
            "springs.bend.stiffness: is -1 N/m, must not be negative",
        ),
        ("Scene(spheres: [(friction: -0.5)])", "colliders[0].friction: is -0.5 (dimensionless), must not be negative"),
        ("Scene(cloth: (resolution: (4, 4), pins: [Vertex(99)]))", "cloth.pins[0]: Vertex(99) names vertex 99"),
        ("Scene(cloth: (resolution: (70000, 70000)))", "cloth.resolution: grid 70000x70000 needs about"),
    ];
    for (text, expected) in cases {
        let err = Scene::from_ron_str(text).unwrap_err().to_string();
        assert!(err.contains(expected), "{text}\n  gave: {err}\n  expected: {expected}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = Scene::from_ron_str(&text);
    }

    #[test]
    fn random_field_values_never_panic(
        nx in any::<u32>(), ny in any::<u32>(),
        size in any::<f64>(), mass in any::<f64>(), k in any::<f64>(), radius in any::<f64>(),
        friction in any::<f64>(), dt in any::<f64>(), substeps in any::<u32>(), pin in any::<u32>(),
    ) {
        let text = format!(
            "Scene(cloth: (resolution: ({nx}, {ny}), size: ({size:?}, 1.0), mass: Total({mass:?}), pins: [Vertex({pin})]),
                   springs: (structural: (stiffness: {k:?}, damping: 0.0)),
                   spheres: [(radius: {radius:?}, friction: {friction:?})],
                   time: (frame_dt: {dt:?}, substeps: Fixed({substeps})))"
        );
        if let Ok(scene) = Scene::from_ron_str(&text) {
            // A scene that passes validation has usable values everywhere.
            prop_assert!(scene.vertex_mass() > 0.0 && scene.substep_dt() > 0.0);
            prop_assert!(scene.vertex_count() >= 4);
            prop_assert!(scene.substeps_per_frame() <= cloth_core::budget::MAX_SUBSTEPS_PER_FRAME);
            prop_assert!(cloth_core::stability::stable_substep(&scene) > 0.0);
        }
    }
}

#[test]
fn a_byte_order_mark_is_accepted() {
    let text = format!("\u{feff}{}", Scene::default().to_ron_string());
    assert_eq!(Scene::from_ron_str(&text).unwrap(), Scene::default());
}

#[test]
fn an_effect_listed_twice_is_refused_naming_it() {
    let err = Scene::from_ron_str("Scene(effects: [Gravity, StructuralSprings, Gravity])").unwrap_err().to_string();
    assert!(err.contains("Gravity is listed twice"), "{err}");
}

/// A device, a folder or a file larger than the limit is refused before it is read.
#[test]
fn only_regular_files_of_bounded_size_are_read() {
    for path in ["/dev/zero", "/tmp"] {
        let err = Scene::load(std::path::Path::new(path)).unwrap_err().to_string();
        assert!(err.contains("not a regular file"), "{path}: {err}");
    }
    let big = std::env::temp_dir().join(format!("cloth-big-scene-{}.ron", std::process::id()));
    let padding = " ".repeat(cloth_core::validation::MAX_SCENE_BYTES as usize);
    std::fs::write(&big, format!("Scene(){padding}")).unwrap();
    let err = Scene::load(&big).unwrap_err().to_string();
    std::fs::remove_file(&big).unwrap();
    assert!(err.contains("larger than 1048576 bytes"), "{err}");
}

/// A million bad pins give a short message: the first problems and a count of the rest.
#[test]
fn the_list_of_problems_is_capped() {
    let mut scene = Scene::default();
    scene.cloth.pins = vec![cloth_core::scene::Pin::Vertex(u32::MAX); 1_000_000];
    let err = scene.validate().unwrap_err();
    assert_eq!(err.problems().len(), cloth_core::validation::MAX_PROBLEMS + 1);
    let text = err.to_string();
    assert!(text.contains("999980 more problem(s) not listed") && text.len() < 8_000, "{}", &text[..200]);
}

/// Extreme but finite values, and counts that would run for years, are refused by validation
/// with the field named, before anything runs.
#[test]
fn values_f32_cannot_carry_and_unbounded_work_are_refused() {
    let cases = [
        ("Scene(cloth: (mass: PerVertex(1e-300)))", "cloth.mass.PerVertex: is 1e-300"),
        ("Scene(cloth: (mass: Total(1e300)))", "cloth.mass.Total: is 1e300"),
        ("Scene(gravity: (0.0, -1e308, 0.0))", "gravity[1]: is -1e308"),
        ("Scene(springs: (shear: (stiffness: 200.0, damping: 1e30)))", "springs.shear.damping: is 1e30"),
        (
            "Scene(cloth: (orientation: Axes(u: (1e300, 0.0, 0.0), v: (0.0, 0.0, 1.0))))",
            "cloth.orientation.u[0]: is 1e300",
        ),
        ("Scene(cloth: (resolution: (1000, 1000), mass: Total(1e-10)))", "cloth.mass: gives 1e-16 kg a vertex"),
        ("Scene(time: (substeps: Fixed(4294967295)))", "time.substeps: is Fixed(4294967295), more than the 1000000"),
        ("Scene(time: (frame_dt: 10000000000.0, substeps: Auto))", "time.substeps: is Auto, which needs"),
        ("Scene(time: (frames: 4294967295))", "time.frames: is 4294967295, more than the 10000000"),
    ];
    for (text, expected) in cases {
        let err = Scene::from_ron_str(text).unwrap_err().to_string();
        assert!(err.contains(expected), "{text}\n  gave: {err}\n  expected: {expected}");
    }
    // A substep that no allowed count makes stable says so instead of naming an impossible one.
    let mut stiff = Scene::default();
    stiff.springs.structural.stiffness = 1e15;
    let warnings = stiff.validate().unwrap();
    assert!(warnings[0].fix.contains("no substep count up to the 1000000 allowed is stable"), "{:?}", warnings[0]);
}

#[test]
fn the_work_budget_refuses_a_command_that_would_run_for_hours() {
    use cloth_core::budget::WorkBudget;
    let scene = Scene::default();
    assert_eq!(WorkBudget::CPU.check(&scene, 300), Ok(1024 * 40 * 300));
    let refused = WorkBudget::CPU.check(&scene, 9_000_000).unwrap_err();
    assert!(refused.message.contains("more than the 1e11 one command may run on cpu"), "{refused}");
    assert!(refused.fix.contains("at most 2441406 frames"), "{refused}");
    assert!(WorkBudget::GPU.check(&scene, 9_000_000).is_ok());
    assert!(WorkBudget::GPU.check(&scene, 20_000_000).unwrap_err().message.contains("more than the 10000000"));
    // When one frame alone is over the budget, fewer frames is not offered as the fix.
    let mut huge = Scene::default();
    huge.cloth.resolution = [4096, 4096];
    huge.time.substeps = cloth_core::scene::Substeps::Fixed(1_000_000);
    let refused = WorkBudget::CPU.check(&huge, 1).unwrap_err();
    assert!(refused.fix.contains("one frame alone is 1.678e13"), "{refused}");
}
