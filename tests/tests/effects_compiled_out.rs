//! An effect a scene leaves out costs nothing: in the pipeline built for the scene, the code of an
//! absent effect is only reachable behind a branch on an override constant that is `false`.
//!
//! The check runs on naga's IR after the pipeline's override constants are applied (what wgpu
//! compiles): it walks the entry point and every function it calls, skips the branches whose
//! condition is a constant, and collects the functions that can still run. A driver then never
//! sees the skipped code as reachable: the constant branch is folded away.

use std::collections::BTreeSet;

use cloth_core::colliders::ColliderKind;
use cloth_core::{Effect, EffectSet, Integrator, Scene};
use naga::{Expression, Handle, Literal, Module, Statement};

/// The functions that implement each effect (called only when it is present).
fn work_of(effect: Effect) -> &'static [&'static str] {
    match effect {
        Effect::Gravity => &["gravity_force"],
        Effect::StructuralSprings | Effect::ShearSprings | Effect::BendSprings => {
            &["add_spring_force", "project_spring"]
        }
        Effect::SpringDamping => &[],
        Effect::Contact => {
            &["contact_force", "collider_surface", "collider_center", "project_swept", "project_colliders"]
        }
        Effect::Friction => &["friction_force", "friction_holds", "contact_friction"],
        Effect::AirDrag => &["air_drag_force"],
        Effect::Wind => &["wind_force", "wind_velocity", "grid_normal"],
        Effect::MovingPins | Effect::MovingColliders => &["motion_displacement", "motion_velocity"],
        Effect::SelfCollision => &[
            "self_collision_force",
            "repulsion_force",
            "far_candidate",
            "limit_step",
            "limit_velocity",
            "record_motion",
        ],
    }
}

/// The value of a boolean or integer constant expression, if it is one.
fn constant(module: &Module, exprs: &naga::Arena<Expression>, e: Handle<Expression>) -> Option<u64> {
    let literal = |l: &Literal| match *l {
        Literal::Bool(b) => Some(b as u64),
        Literal::U32(v) => Some(v as u64),
        Literal::I32(v) => Some(v as u64),
        _ => None,
    };
    match &exprs[e] {
        Expression::Literal(l) => literal(l),
        Expression::Constant(c) => constant(module, &module.global_expressions, module.constants[*c].init),
        Expression::Unary { op: naga::UnaryOperator::LogicalNot, expr } => {
            constant(module, exprs, *expr).map(|v| (v == 0) as u64)
        }
        Expression::Binary { op, left, right } => {
            let (a, b) = (constant(module, exprs, *left), constant(module, exprs, *right));
            use naga::BinaryOperator::*;
            match op {
                // `false && x` and `true || x` are decided by one side.
                LogicalAnd if a == Some(0) || b == Some(0) => Some(0),
                LogicalOr if a == Some(1) || b == Some(1) => Some(1),
                LogicalAnd => Some((a? != 0 && b? != 0) as u64),
                LogicalOr => Some((a? != 0 || b? != 0) as u64),
                Equal => Some((a? == b?) as u64),
                NotEqual => Some((a? != b?) as u64),
                Less => Some((a? < b?) as u64),
                LessEqual => Some((a? <= b?) as u64),
                Greater => Some((a? > b?) as u64),
                GreaterEqual => Some((a? >= b?) as u64),
                _ => None,
            }
        }
        _ => None,
    }
}

/// Collects the names of the functions that can run from `block` of `function`, recursively;
/// returns whether the block can finish (no `return` on every path through it).
fn reachable(module: &Module, function: &naga::Function, block: &naga::Block, found: &mut BTreeSet<String>) -> bool {
    for statement in block.iter() {
        let continues = match statement {
            Statement::Call { function: callee, .. } => {
                let f = &module.functions[*callee];
                if found.insert(f.name.clone().unwrap_or_default()) {
                    reachable(module, f, &f.body, found);
                }
                true
            }
            Statement::If { condition, accept, reject } => match constant(module, &function.expressions, *condition) {
                Some(0) => reachable(module, function, reject, found),
                Some(_) => reachable(module, function, accept, found),
                None => {
                    let a = reachable(module, function, accept, found);
                    let r = reachable(module, function, reject, found);
                    a || r
                }
            },
            Statement::Block(b) => reachable(module, function, b, found),
            Statement::Loop { body, continuing, .. } => {
                reachable(module, function, body, found);
                reachable(module, function, continuing, found);
                true
            }
            Statement::Switch { selector, cases } => {
                let chosen = constant(module, &function.expressions, *selector).and_then(|v| {
                    let matches = |c: &&naga::SwitchCase| match c.value {
                        naga::SwitchValue::U32(x) => x as u64 == v,
                        naga::SwitchValue::I32(x) => x as u64 == v,
                        naga::SwitchValue::Default => false,
                    };
                    cases
                        .iter()
                        .position(|c| matches(&c))
                        .or_else(|| cases.iter().position(|c| c.value == naga::SwitchValue::Default))
                });
                match chosen {
                    // A constant selector runs its case, and the ones it falls through to.
                    Some(mut k) => loop {
                        let continues = reachable(module, function, &cases[k].body, found);
                        if !cases[k].fall_through || k + 1 == cases.len() {
                            break continues;
                        }
                        k += 1;
                    },
                    None => {
                        let mut any = false;
                        for case in cases {
                            any |= reachable(module, function, &case.body, found);
                        }
                        any
                    }
                }
            }
            Statement::Return { .. } | Statement::Kill => false,
            _ => true,
        };
        if !continues {
            return false;
        }
    }
    true
}

/// The shading language a pipeline is written in.
#[derive(Clone, Copy, Debug)]
enum Language {
    /// `shaders/wgsl/`, as the wgpu backend builds it (override constants named).
    Wgsl,
    /// `shaders/glsl/`, as the vulkano backend builds it (specialization constants by id).
    Glsl,
}

/// A GLSL kernel of `shaders/glsl/` with its `#include`s inlined, for naga's GLSL front end
/// (which has no include directive); the workgroup size is a plain literal there.
fn glsl_source(kernel: &str) -> String {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders/glsl");
    fn inline(dir: &std::path::Path, name: &str, out: &mut String) {
        let text = std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        for line in text.lines() {
            if let Some(included) = line.trim().strip_prefix("#include ") {
                inline(dir, included.trim_matches('"'), out);
            } else if !line.contains("GL_GOOGLE_include_directive") {
                *out += line;
                out.push('\n');
            }
        }
    }
    let mut out = String::new();
    inline(&dir, kernel, &mut out);
    // naga's GLSL front end has no atomics: a no-op function of the same shape stands in (it
    // changes no branch, so not what is reachable).
    let stub = "void naga_atomic_max(uint a, uint b) {}\n";
    // (And no specialization constants for sizes: the tiled kernel's workgroup and shared arrays
    // keep their defaults, the default tile's.)
    let out = out
        .replace("local_size_x_id = 100", "local_size_y = 1")
        .replace(", local_size_x_id = 102, local_size_y_id = 103", "")
        .replace("layout(constant_id = 104) const uint TILE_CELLS", "const uint TILE_CELLS")
        .replace("atomicMax(", "naga_atomic_max(");
    match out.find('\n') {
        Some(end_of_version) => format!("{}{stub}{}", &out[..=end_of_version], &out[end_of_version + 1..]),
        None => out,
    }
}

/// The functions the pipeline of `source`'s `entry` can run with the scene's effects, its collider
/// kinds and the stage constant `stage` set, as the backend of `language` builds it.
fn pipeline_work(
    language: Language,
    source: &str,
    entry: &str,
    (effects, kinds): (EffectSet, &[ColliderKind]),
    stage: Option<(&str, u32)>,
) -> BTreeSet<String> {
    let module = match language {
        Language::Wgsl => naga::front::wgsl::parse_str(source).expect("the shader parses"),
        Language::Glsl => naga::front::glsl::Frontend::default()
            .parse(&naga::front::glsl::Options::from(naga::ShaderStage::Compute), source)
            .unwrap_or_else(|e| panic!("the GLSL shader parses: {}", e.emit_to_string(source))),
    };
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .expect("the shader validates");
    // WGSL overrides are keyed by name; GLSL specialization constants by their `constant_id`
    // (the effects in the order of `shader_constants`, the stage at 101), as vulkano sets them.
    let mut constants = naga::back::PipelineConstants::default();
    for (id, (name, on)) in effects.shader_constants().into_iter().enumerate() {
        let key = match language {
            Language::Wgsl => name.to_string(),
            Language::Glsl => id.to_string(),
        };
        constants.insert(key, if on { 1.0 } else { 0.0 });
    }
    for kind in ColliderKind::ALL {
        let key = match language {
            Language::Wgsl => kind.shader_constant_name().to_string(),
            Language::Glsl => (cloth_gpu::plan::COLLIDER_CONSTANT_IDS + kind.code()).to_string(),
        };
        constants.insert(key, if kinds.contains(&kind) { 1.0 } else { 0.0 });
    }
    match (language, stage) {
        (Language::Wgsl, stage) => {
            constants.insert("WORKGROUP_SIZE".to_string(), 64.0);
            if let Some((name, value)) = stage {
                constants.insert(name.to_string(), value as f64);
            }
        }
        (Language::Glsl, Some((_, value))) => {
            constants.insert("101".to_string(), value as f64);
        }
        (Language::Glsl, None) => {}
    }
    let (module, _) = naga::back::pipeline_constants::process_overrides(
        &module,
        &info,
        Some((naga::ShaderStage::Compute, entry)),
        &constants,
    )
    .expect("the overrides apply");
    let entry_point = module.entry_points.iter().find(|e| e.name == entry).expect("the entry point exists");
    let mut found = BTreeSet::new();
    reachable(&module, &entry_point.function, &entry_point.function.body, &mut found);
    found
}

/// Every pipeline a scene of `integrator`, `effects` and collider kinds builds in `language`, with
/// what it can run.
fn pipelines_with(
    language: Language,
    integrator: Integrator,
    effects: EffectSet,
    kinds: &[ColliderKind],
) -> Vec<(String, BTreeSet<String>)> {
    let (stage, stages): (&str, Vec<u32>) = match integrator {
        Integrator::SemiImplicitEuler => ("STAGE", vec![0]),
        Integrator::VelocityVerlet => ("STAGE", vec![1, 2]),
        Integrator::RungeKutta4 => ("STAGE", vec![3, 4, 5, 6]),
        Integrator::Xpbd => ("XPBD_PASS", vec![0, 1, 2, 3]),
        Integrator::Vbd => ("VBD_PASS", vec![0, 1, 2]),
        Integrator::BackwardEuler => ("IMPLICIT_PASS", (0..=8).collect()),
    };
    let (source, entry) = match (language, integrator) {
        (Language::Wgsl, Integrator::Xpbd) => (cloth_wgpu::XPBD_SHADER.to_string(), "xpbd"),
        (Language::Wgsl, Integrator::Vbd) => (cloth_wgpu::VBD_SHADER.to_string(), "vbd"),
        (Language::Wgsl, Integrator::BackwardEuler) => (cloth_wgpu::IMPLICIT_SHADER.to_string(), "implicit"),
        (Language::Wgsl, _) => (cloth_wgpu::STEP_SHADER.to_string(), "substep"),
        (Language::Glsl, Integrator::Xpbd) => (glsl_source("xpbd.comp"), "main"),
        (Language::Glsl, Integrator::Vbd) => (glsl_source("vbd.comp"), "main"),
        (Language::Glsl, Integrator::BackwardEuler) => (glsl_source("implicit.comp"), "main"),
        (Language::Glsl, _) => (glsl_source("cloth_step.comp"), "main"),
    };
    let mut all: Vec<(String, BTreeSet<String>)> = stages
        .into_iter()
        .map(|n| {
            let name = format!("{language:?} {integrator:?} {stage} {n}");
            (name, pipeline_work(language, &source, entry, (effects, kinds), Some((stage, n))))
        })
        .collect();
    if integrator == Integrator::SemiImplicitEuler {
        // The tiled kernel that fuses Euler substeps (cloth_gpu::geometry), at the default tile.
        let (source, entry) = match language {
            Language::Wgsl => (cloth_wgpu::tiled_shader_source(&cloth_gpu::geometry::DEFAULT_TILES[0]), "substeps"),
            Language::Glsl => (glsl_source("cloth_step_tiled.comp"), "main"),
        };
        let work = pipeline_work(language, &source, entry, (effects, kinds), None);
        all.push((format!("{language:?} tiled Euler"), work));
    }
    all
}

/// [`pipelines_with`] every collider kind.
fn pipelines(language: Language, integrator: Integrator, effects: EffectSet) -> Vec<(String, BTreeSet<String>)> {
    pipelines_with(language, integrator, effects, &ColliderKind::ALL)
}

/// The functions that evaluate a collider kind's signed distance and surface (a plane's distance
/// is one dot product, inline).
fn work_of_kind(kind: ColliderKind) -> Vec<String> {
    let mut work = vec![format!("{}_surface", kind.name())];
    if kind != ColliderKind::Plane {
        work.push(format!("{}_distance", kind.name()));
    }
    work
}

/// A collider kind no collider of the scene has costs nothing either: its signed distance cannot
/// run in any pipeline, while the kinds present can.
#[test]
fn absent_collider_kinds_leave_no_reachable_work() {
    let effects = Scene::default().effects;
    for (language, integrator) in
        [Language::Wgsl, Language::Glsl].into_iter().flat_map(|l| Integrator::ALL.map(|i| (l, i)))
    {
        for absent in ColliderKind::ALL {
            let present: Vec<ColliderKind> = ColliderKind::ALL.into_iter().filter(|k| *k != absent).collect();
            for (pipeline, work) in pipelines_with(language, integrator, effects, &present) {
                for f in work_of_kind(absent) {
                    assert!(!work.contains(&f), "{pipeline}: no {absent:?} collider, but `{f}` can run: {work:?}");
                }
            }
        }
        // The pipeline that evaluates the colliders' surfaces: the force kernel's, VBD's colour
        // pass, backward Euler's linearisation (XPBD projects them: not all kinds have one).
        let evaluating = match integrator {
            Integrator::Vbd | Integrator::BackwardEuler => 1,
            _ => 0,
        };
        let (pipeline, work) = pipelines_with(language, integrator, effects, &ColliderKind::ALL).remove(evaluating);
        if integrator != Integrator::Xpbd {
            for f in ColliderKind::ALL.into_iter().flat_map(work_of_kind) {
                assert!(work.contains(&f), "{pipeline}: every kind present, `{f}` should be reachable: {work:?}");
            }
        }
    }
}

#[test]
fn absent_effects_leave_no_reachable_work_in_the_pipelines() {
    let every = EffectSet::from_iter(Effect::ALL);
    let scenes: Vec<(&str, EffectSet)> = vec![
        ("the default drape", Scene::default().effects),
        ("springs only", [Effect::StructuralSprings, Effect::ShearSprings, Effect::BendSprings].into_iter().collect()),
        ("gravity only", EffectSet::empty().with(Effect::Gravity)),
        ("everything but the wind", every.without(Effect::Wind)),
        ("everything but moving things", every.without(Effect::MovingPins).without(Effect::MovingColliders)),
    ];
    for (language, integrator) in
        [Language::Wgsl, Language::Glsl].into_iter().flat_map(|l| Integrator::ALL.map(|i| (l, i)))
    {
        for (name, effects) in &scenes {
            for (pipeline, work) in pipelines(language, integrator, *effects) {
                for effect in Effect::ALL {
                    let needed_by_another = |f: &&str| {
                        Effect::ALL.iter().any(|e| *e != effect && effects.contains(*e) && work_of(*e).contains(f))
                    };
                    if effects.contains(effect) {
                        continue;
                    }
                    for f in work_of(effect).iter().filter(|f| !needed_by_another(f)) {
                        assert!(
                            !work.contains(*f),
                            "{name}, {pipeline}: {effect:?} is absent but `{f}` can run: {work:?}"
                        );
                    }
                }
            }
        }
    }
}

/// The check can fail: with every effect present, their work is reachable.
#[test]
fn present_effects_have_reachable_work() {
    let every = EffectSet::from_iter(Effect::ALL);
    for language in [Language::Wgsl, Language::Glsl] {
        let euler: BTreeSet<String> = pipelines(language, Integrator::SemiImplicitEuler, every).remove(0).1;
        for f in [
            "gravity_force",
            "add_spring_force",
            "air_drag_force",
            "wind_force",
            "grid_normal",
            "contact_force",
            "friction_force",
            "motion_displacement",
            "self_collision_force",
            "repulsion_force",
            "far_candidate",
            "limit_step",
            "record_motion",
        ] {
            assert!(euler.contains(f), "{language:?} Euler with every effect: `{f}` should be reachable: {euler:?}");
        }
        let predict = pipelines(language, Integrator::Xpbd, every).remove(0).1;
        assert!(predict.contains("wind_force") && predict.contains("motion_displacement"), "{language:?}: {predict:?}");
        let predict = pipelines(language, Integrator::Vbd, every).remove(0).1;
        assert!(predict.contains("wind_force") && predict.contains("repulsion_force"), "{language:?}: {predict:?}");
        let linearise = pipelines(language, Integrator::BackwardEuler, every).remove(1).1;
        for f in ["gravity_force", "add_spring_force", "contact_force", "friction_force", "repulsion_force"] {
            assert!(linearise.contains(f), "{language:?} backward Euler: `{f}` should be reachable: {linearise:?}");
        }
    }
}
