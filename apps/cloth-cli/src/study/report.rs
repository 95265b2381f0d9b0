//! The study's Markdown report (`--report docs/accuracy.md`): the command that regenerates it,
//! the machine, the plot, and for each scene: which integrator and step to take for an error
//! budget and a frame-time budget, the largest step with a bounded error, what the coarsest step
//! gives, the measured orders, the stability limits and every run. Everything with a number in
//! it, the sentences that discuss the numbers included, is generated from the runs.

use std::fmt::Write;

use cloth_core::Integrator;

use super::bisection::Outcome;
use super::plot::pareto_front;
use super::{Budgets, Row, Study};

/// File names of the study's outputs beside the report.
pub struct Files {
    pub csv: String,
    pub svg: String,
    pub png: String,
}

/// Error budgets the report picks an integrator for, m.
const BUDGETS_M: [f64; 6] = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

/// Today's date (UTC) as YYYY-MM-DD, from the system clock.
fn today() -> String {
    let days =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs() / 86_400).unwrap_or(0)
            as i64;
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

/// The machine in words: CPU model, logical CPUs, operating system.
fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("PRETTY_NAME="))
                .map(|l| l.trim_start_matches("PRETTY_NAME=").trim_matches('"').to_string())
        })
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    format!("{cpu}, {threads} logical CPUs, {os}")
}

/// The command line that ran this study, as a `cargo run` command.
///
/// `--csv` is left out: the report copies its CSV and plot beside itself whatever the CSV's path.
fn command() -> String {
    let mut args = Vec::new();
    let mut given = std::env::args().skip(1);
    while let Some(a) = given.next() {
        if a == "--csv" {
            given.next();
        } else if !a.starts_with("--csv=") {
            args.push(if a.contains(' ') { format!("'{a}'") } else { a });
        }
    }
    format!("cargo run --release -p cloth-cli -- {}", args.join(" "))
}

fn sci(v: f64) -> String {
    if v.is_finite() { format!("{v:.2e}") } else { "—".into() }
}

fn ms(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// RMS error below which an f32 run has reached the rounding of its positions (about 1 ulp of a
/// coordinate near 1.5 m, 1.2e-7 m, times a few), m.
const F32_FLOOR_M: f64 = 1e-6;

/// Measured order between consecutive substep counts of one backend and integrator,
/// `log(e₁/e₂) / log(Δt₁/Δt₂)` over the finite runs, each with whether the finer run is at the
/// f32 rounding floor.
fn orders(study: &Study, backend: &str, integrator: Integrator) -> Vec<(f64, bool)> {
    let runs: Vec<_> =
        study.rows.iter().filter(|r| r.backend == backend && r.integrator == integrator && r.plottable()).collect();
    runs.windows(2)
        .map(|w| {
            let order = (w[0].rms_error_m / w[1].rms_error_m).ln() / (w[0].dt / w[1].dt).ln();
            (order, backend != "cpu-f64" && w[1].rms_error_m < F32_FLOOR_M)
        })
        .collect()
}

fn has_colliders(scene: &cloth_core::Scene) -> bool {
    scene.effects.contains(cloth_core::Effect::Contact) && !scene.colliders.is_empty()
}

/// Dispatches of one XPBD substep of `scene` on the GPU backends (as their `passes.rs` plan them).
fn xpbd_dispatches(scene: &cloth_core::Scene) -> u32 {
    let colors = cloth_core::ClothModel::new(scene).spring_colors();
    let non_empty = (0..cloth_core::coloring::COLOR_COUNT).filter(|&c| !colors.color(c).is_empty()).count() as u32;
    2 + cloth_core::integrator::XPBD_ITERATIONS * (non_empty + u32::from(has_colliders(scene)))
}

/// Error budgets of the two-budget table, m RMS.
const TWO_BUDGET_ERRORS_M: [f64; 5] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6];

/// The backend the budget tables and the discussion judge by: the first GPU backend that ran
/// (its costs are GPU timestamps), else the first backend that ran.
fn judged_backend(study: &Study) -> Option<&str> {
    let ran: Vec<&str> = study.adapters.iter().map(|(b, _)| b.as_str()).collect();
    ran.iter().copied().find(|b| !b.starts_with("cpu")).or_else(|| ran.first().copied())
}

/// A run's cost per frame, ms.
fn frame_ms(study: &Study, r: &Row) -> f64 {
    r.cost_ms() * study.scene.time.frame_dt
}

/// `integrator × substeps`, the report's name of a run.
fn run_name(r: &Row) -> String {
    format!("{} × {}", r.integrator.name(), r.substeps)
}

/// The cheapest usable run of `backend` within `error_m` and, when given, `frame_budget_ms`.
fn cheapest<'a>(study: &'a Study, backend: &str, error_m: f64, frame_budget_ms: Option<f64>) -> Option<&'a Row> {
    study
        .rows
        .iter()
        .filter(|r| r.backend == backend && r.plottable() && r.rms_error_m <= error_m)
        .filter(|r| frame_budget_ms.is_none_or(|b| frame_ms(study, r) <= b))
        .min_by(|x, y| x.cost_ms().total_cmp(&y.cost_ms()))
}

/// The run with the fewest substeps (the largest step) of `integrator` on `backend` whose error
/// is within `bound_m`.
fn largest_bounded_step<'a>(study: &'a Study, backend: &str, integrator: Integrator, bound_m: f64) -> Option<&'a Row> {
    study
        .rows
        .iter()
        .filter(|r| r.backend == backend && r.integrator == integrator && r.plottable() && r.rms_error_m <= bound_m)
        .min_by_key(|r| r.substeps)
}

/// The integrators that ran on `backend`, in the order of [`Integrator::ALL`].
fn integrators_of(study: &Study, backend: &str) -> Vec<Integrator> {
    Integrator::ALL
        .into_iter()
        .filter(|i| study.rows.iter().any(|r| r.backend == backend && r.integrator == *i))
        .collect()
}

fn collider_radius(scene: &cloth_core::Scene) -> Option<f64> {
    scene.colliders.iter().filter_map(|c| c.sphere().map(|s| s.radius)).reduce(f64::min)
}

/// A ratio in words: one decimal below 10, whole numbers from 10.
fn ratio(r: f64) -> String {
    if r >= 10.0 { format!("{r:.0}") } else { format!("{r:.1}") }
}

/// "`r` times more accurate", or "as accurate" where the errors' ratio `r` (≥ 1) would print as
/// 1.0; `than` adds the comparison's word ("than" or "as").
fn more_accurate(r: f64, than: bool) -> String {
    let (phrase, word) = if r < 1.05 {
        ("as accurate".to_string(), "as")
    } else {
        (format!("{} times more accurate", ratio(r)), "than")
    };
    if than { format!("{phrase} {word}") } else { phrase }
}

/// `a`, `a and b`, `a, b and c`.
fn and_list<S: AsRef<str>>(items: &[S]) -> String {
    match items {
        [] => String::new(),
        [one] => one.as_ref().to_string(),
        [init @ .., last] => {
            format!("{} and {}", init.iter().map(|s| s.as_ref()).collect::<Vec<_>>().join(", "), last.as_ref())
        }
    }
}

/// Sentences that say what one scene's numbers show on the judged backend.
fn discussion(study: &Study, budgets: &Budgets, backend: &str) -> Vec<String> {
    let mut said = Vec::new();
    let bound = budgets.error_bound_m;
    let coarsest = study.rows.iter().filter(|r| r.backend == backend).map(|r| r.substeps).min().unwrap_or(1);
    // Who takes the largest step within the error bound.
    let mut steps: Vec<(Integrator, &Row)> = integrators_of(study, backend)
        .into_iter()
        .filter_map(|i| largest_bounded_step(study, backend, i, bound).map(|r| (i, r)))
        .collect();
    steps.sort_by_key(|(_, r)| r.substeps);
    if let Some((_, r)) = steps.first() {
        let ties: Vec<&str> = steps.iter().filter(|(_, o)| o.substeps == r.substeps).map(|(i, _)| i.name()).collect();
        let others: Vec<String> = steps
            .iter()
            .filter(|(_, o)| o.substeps != r.substeps)
            .map(|(i, o)| format!("{} {}", i.name(), o.substeps))
            .collect();
        let mut text = format!(
            "Within {bound:.0e} m the largest step is {} substep{} a frame (Δt = {:.2e} s), taken by {}",
            r.substeps,
            if r.substeps == 1 { "" } else { "s" },
            r.dt,
            and_list(&ties)
        );
        if !others.is_empty() {
            text += &format!("; the others need {} substeps a frame", and_list(&others));
        }
        let missing: Vec<&str> = integrators_of(study, backend)
            .into_iter()
            .filter(|i| !steps.iter().any(|(j, _)| j == i))
            .map(|i| i.name())
            .collect();
        if !missing.is_empty() {
            text += &format!(
                ", and {} reach{} it at no step of the sweep",
                and_list(&missing),
                if missing.len() == 1 { "es" } else { "" }
            );
        }
        said.push(text + ".");
    } else {
        said.push(format!("No run of the sweep stays within {bound:.0e} m."));
    }
    // The coarsest step: who diverges, and what the implicit ones dissipate.
    let at_coarsest: Vec<&Row> = study.rows.iter().filter(|r| r.backend == backend && r.substeps == coarsest).collect();
    let diverged: Vec<&str> = at_coarsest.iter().filter(|r| r.diverged).map(|r| r.integrator.name()).collect();
    if !diverged.is_empty() {
        said.push(format!(
            "At {coarsest} substep{} a frame {} diverge{}.",
            if coarsest == 1 { "" } else { "s" },
            and_list(&diverged),
            if diverged.len() == 1 { "s" } else { "" }
        ));
    }
    let energies: Vec<String> = at_coarsest
        .iter()
        .filter(|r| !r.diverged && r.integrator.unconditionally_stable())
        .map(|r| {
            let (amount, side) = if r.energy_dissipated_j >= 0.0 {
                (r.energy_dissipated_j, "below")
            } else {
                (-r.energy_dissipated_j, "above")
            };
            format!("{} {amount:.3} J {side}", r.integrator.name())
        })
        .collect();
    if !energies.is_empty() {
        said.push(format!(
            "At {coarsest} substep{} a frame the methods without a stability limit end, against the reference's \
             final energy, {}: below is energy dissipated (numerical damping), above is energy the springs \
             still hold because the step did not converge them.",
            if coarsest == 1 { "" } else { "s" },
            and_list(&energies)
        ));
    }
    // Equal cost: each method without a stability limit at the coarsest step against the most
    // accurate run that costs no more.
    for r in at_coarsest.iter().filter(|r| r.plottable() && r.integrator.unconditionally_stable()) {
        let best = study
            .rows
            .iter()
            .filter(|o| o.backend == backend && o.plottable() && o.cost_ms() <= r.cost_ms())
            .min_by(|x, y| x.rms_error_m.total_cmp(&y.rms_error_m));
        if let Some(best) = best
            && best.integrator != r.integrator
        {
            said.push(format!(
                "For the {} ms a frame of {} (error {}), {} is {} ({}, {} ms a frame).",
                ms(frame_ms(study, r)),
                run_name(r),
                sci(r.rms_error_m),
                run_name(best),
                more_accurate(r.rms_error_m / best.rms_error_m, false),
                sci(best.rms_error_m),
                ms(frame_ms(study, best))
            ));
        }
    }
    // Backward Euler against VBD at the coarsest step: the two implicit-Euler solvers.
    let n = coarsest;
    let find = |i: Integrator| {
        study.rows.iter().find(|r| r.backend == backend && r.integrator == i && r.substeps == n && r.plottable())
    };
    if let (Some(be), Some(vbd)) = (find(Integrator::BackwardEuler), find(Integrator::Vbd)) {
        let (better, worse) = if be.rms_error_m <= vbd.rms_error_m { (be, vbd) } else { (vbd, be) };
        said.push(format!(
            "At {n} substep{} a frame {} ({} iterations a substep) is {} {} ({}), at {:.2} times its cost.",
            if n == 1 { "" } else { "s" },
            better.integrator.name(),
            better.solver_iterations_per_substep.map(|k| format!("{k:.1}")).unwrap_or_else(|| "—".into()),
            more_accurate(worse.rms_error_m / better.rms_error_m, true),
            worse.integrator.name(),
            worse.solver_iterations_per_substep.map(|k| format!("{k:.1} iterations")).unwrap_or_default(),
            better.cost_ms() / worse.cost_ms()
        ));
    }
    said
}

/// Writes one markdown table row of cells.
fn table_row(md: &mut String, cells: &[String]) {
    let _ = writeln!(md, "| {} |", cells.join(" | "));
}

fn table_head(md: &mut String, cells: &[&str]) {
    let _ = writeln!(md, "| {} |\n|{}", cells.join(" | "), "---|".repeat(cells.len()));
}

pub fn markdown(studies: &[Study], budgets: &Budgets, files: &Files) -> String {
    let mut md = String::new();
    let build = if cfg!(debug_assertions) { "debug build" } else { "release build" };
    let _ = writeln!(md, "# What accuracy costs in time\n");
    let _ = writeln!(
        md,
        "<!-- Generated by `cloth study accuracy --report`: edit apps/cloth-cli/src/study/report.rs, not this file. -->\n"
    );
    let _ = writeln!(md, "Regenerate this page (tables, plot and CSV) with:\n\n```sh\n{}\n```\n", command());
    let _ = writeln!(md, "Measured on {} on {} ({build}). Backends and the devices they ran on:\n", today(), machine());
    let mut adapters: Vec<&(String, String)> = Vec::new();
    for a in studies.iter().flat_map(|s| &s.adapters) {
        if !adapters.iter().any(|(b, _)| *b == a.0) {
            adapters.push(a);
        }
    }
    table_head(&mut md, &["backend", "device"]);
    for (backend, adapter) in &adapters {
        table_row(&mut md, &[backend.clone(), adapter.clone()]);
    }
    if adapters.iter().any(|(_, a)| a.contains("llvmpipe")) {
        let _ = writeln!(
            md,
            "\nllvmpipe (lavapipe) is Mesa's Vulkan driver on the CPU: its GPU-backend costs say what the \
             method costs relative to the others on the same device, not what a GPU would take (see \
             [performance.md](performance.md) for GPU figures)."
        );
    }
    for study in studies {
        for (backend, integrator, reason) in &study.skipped {
            let _ = writeln!(md, "\nSkipped on {}: {backend} {integrator}: {reason}", study.scene.name);
        }
    }

    let _ = writeln!(md, "\n## The study\n");
    let _ = writeln!(
        md,
        "Every run starts from its scene's initial state and is compared, vertex by vertex, with the f64 \
         CPU reference running RK4 at 8 times the finest step of the sweep (or finer, at half RK4's \
         predicted stability bound, where its springs need it). Each run advances one frame per call, as \
         an interactive application does (on the GPU backends one submission per frame). Cost is \
         milliseconds per simulated second: the sum of the frames' GPU time from timestamp queries on \
         the GPU backends, wall-clock time from the first frame to the read-back on the CPU backends; \
         per frame, it is that times the frame's {:.4} s. A run **diverged** when a position is not \
         finite or its RMS error exceeds the cloth's diagonal.\n",
        studies.first().map_or(1.0 / 60.0, |s| s.scene.time.frame_dt)
    );
    table_head(&mut md, &["scene", "what it is", "grid", "effects", "simulated", "reference substeps / frame"]);
    for study in studies {
        let scene = &study.scene;
        let effects: Vec<String> = scene.effects.iter().map(|e| format!("{e:?}")).collect();
        table_row(
            &mut md,
            &[
                format!("`{}`", study.scene_path.display()),
                scene.description.trim_end_matches('.').to_string(),
                format!("{} × {}", scene.cloth.resolution[0], scene.cloth.resolution[1]),
                effects.join(", "),
                format!("{:.3} s ({} frames)", study.frames as f64 * scene.time.frame_dt, study.frames),
                study.reference_substeps.to_string(),
            ],
        );
    }
    let _ = writeln!(
        md,
        "\n![RMS error against cost, a panel per scene: one colour per integrator, one marker per backend, \
         each backend's Pareto front circled]({})\n\nVector version: [{}]({}); every run: [{}]({}).",
        files.png, files.svg, files.svg, files.csv, files.csv
    );

    let _ = writeln!(md, "\n## Which integrator and step, for an error budget and a frame-time budget\n");
    let _ = writeln!(
        md,
        "For each scene, on the backend named: the cheapest run of the sweep whose RMS error is within \
         the row's budget and whose cost per frame is within the column's; **none** when no run meets \
         both. `vbd × 4` means Vertex Block Descent at 4 substeps a frame. Below each table, what the \
         numbers show (sentences generated from the runs)."
    );
    for study in studies {
        let Some(backend) = judged_backend(study) else { continue };
        let _ = writeln!(md, "\n### {} ({backend})\n", study.scene.name);
        let mut head = vec!["RMS error budget (m)".to_string()];
        head.extend(budgets.frame_ms.iter().map(|b| format!("≤ {b} ms / frame")));
        table_head(&mut md, &head.iter().map(String::as_str).collect::<Vec<_>>());
        for error in TWO_BUDGET_ERRORS_M {
            let mut cells = vec![format!("{error:.0e}")];
            for &frame_budget in &budgets.frame_ms {
                cells.push(match cheapest(study, backend, error, Some(frame_budget)) {
                    Some(r) => format!("{} ({} ms)", run_name(r), ms(frame_ms(study, r))),
                    None => "none".into(),
                });
            }
            table_row(&mut md, &cells);
        }
        let _ = writeln!(md);
        for sentence in discussion(study, budgets, backend) {
            let _ = writeln!(md, "- {sentence}");
        }
    }

    let _ = writeln!(md, "\n## Largest step with a bounded error\n");
    let _ = writeln!(
        md,
        "The fewest substeps a frame of the sweep at which each integrator's RMS error stays within {:.0e} m \
         (`--error-bound`), with the energy it dissipates beyond the reference there and, for backward \
         Euler and VBD, the solver iterations it spends a substep (conjugate-gradient iterations over \
         all Newton iterations; VBD sweeps). — when no step of the sweep is within the bound.",
        budgets.error_bound_m
    );
    for study in studies {
        let _ = writeln!(md, "\n### {}\n", study.scene.name);
        table_head(
            &mut md,
            &[
                "backend",
                "integrator",
                "substeps / frame",
                "Δt (s)",
                "RMS error (m)",
                "energy dissipated (J)",
                "solver iterations / substep",
            ],
        );
        for (backend, _) in &study.adapters {
            for integrator in integrators_of(study, backend) {
                let cells = match largest_bounded_step(study, backend, integrator, budgets.error_bound_m) {
                    Some(r) => vec![
                        r.substeps.to_string(),
                        sci(r.dt),
                        sci(r.rms_error_m),
                        format!("{:.3}", r.energy_dissipated_j),
                        r.solver_iterations_per_substep.map(|k| format!("{k:.1}")).unwrap_or_else(|| "—".into()),
                    ],
                    None => vec!["—".into(), String::new(), String::new(), String::new(), String::new()],
                };
                table_row(&mut md, &[vec![backend.clone(), integrator.name().to_string()], cells].concat());
            }
        }
    }

    let coarsest = studies.iter().flat_map(|s| &s.rows).map(|r| r.substeps).min().unwrap_or(1);
    let _ = writeln!(md, "\n## At {coarsest} substep{} a frame\n", if coarsest == 1 { "" } else { "s" });
    let _ = writeln!(
        md,
        "The coarsest step of the sweep, where a real-time application would like to run: error, the \
         energy dissipated beyond the reference, the deepest penetration into a sphere over the run (as \
         a fraction of its radius) and the solver's iterations a substep."
    );
    for study in studies {
        let _ = writeln!(md, "\n### {}\n", study.scene.name);
        let radius = collider_radius(&study.scene);
        table_head(
            &mut md,
            &[
                "backend",
                "integrator",
                "RMS error (m)",
                "energy dissipated (J)",
                "max penetration",
                "solver iterations / substep",
                "ms / frame",
            ],
        );
        for r in study.rows.iter().filter(|r| r.substeps == coarsest) {
            let penetration = match radius {
                Some(radius) if !r.diverged => format!("{:.1}% of the radius", 100.0 * r.max_penetration_m / radius),
                _ => "—".into(),
            };
            let cells = if r.diverged {
                vec!["diverged".into(), String::new(), String::new(), String::new(), ms(frame_ms(study, r))]
            } else {
                vec![
                    sci(r.rms_error_m),
                    format!("{:.3}", r.energy_dissipated_j),
                    penetration,
                    r.solver_iterations_per_substep.map(|k| format!("{k:.1}")).unwrap_or_else(|| "—".into()),
                    ms(frame_ms(study, r)),
                ]
            };
            table_row(&mut md, &[vec![r.backend.clone(), r.integrator.name().to_string()], cells].concat());
        }
    }

    let _ = writeln!(md, "\n## Which integrator for an error budget alone\n");
    let _ = writeln!(
        md,
        "The cheapest run of the sweep whose RMS error is within each budget, per scene and backend (— when \
         no run of the sweep reaches it), whatever it costs. Runs on the Pareto front (nothing both \
         cheaper and more accurate) are the only sensible choices; the table picks among them."
    );
    for study in studies {
        let _ = writeln!(md, "\n### {}\n", study.scene.name);
        let backends: Vec<&str> = study.adapters.iter().map(|(b, _)| b.as_str()).collect();
        let mut head = vec!["budget (m)"];
        head.extend(backends.iter().copied());
        table_head(&mut md, &head);
        for budget in BUDGETS_M {
            let mut cells = vec![format!("{budget:.0e}")];
            for b in &backends {
                cells.push(match cheapest(study, b, budget, None) {
                    Some(r) => format!("{} ({} ms/s)", run_name(r), ms(r.cost_ms())),
                    None => "—".into(),
                });
            }
            table_row(&mut md, &cells);
        }
        for b in &backends {
            let front: Vec<String> =
                pareto_front(&study.rows, b).into_iter().map(|i| run_name(&study.rows[i])).collect();
            let _ = writeln!(md, "\nPareto front on {b}: {}.", front.join(", "));
        }
    }

    let _ = writeln!(md, "\n## Measured order of accuracy\n");
    let _ = writeln!(
        md,
        "Slope of log error against log step between consecutive substep counts (theory: Euler 1, \
         Verlet 2, RK4 4, XPBD, backward Euler and VBD 1). † marks a slope whose finer run is below \
         {F32_FLOOR_M:.0e} m in f32: there the error is the rounding of the positions (1 ulp near 1.5 m \
         is 1.2e-7 m), not the method's, and the slope means nothing. Contact is not smooth: on the \
         scenes with a sphere the slopes say how the error falls, not the methods' order.\n"
    );
    table_head(&mut md, &["scene", "backend", "integrator", "theory", "measured, coarse to fine"]);
    for study in studies {
        for (b, _) in &study.adapters {
            for integrator in Integrator::ALL {
                let o = orders(study, b, integrator);
                if o.is_empty() {
                    continue;
                }
                let list: Vec<String> =
                    o.iter().map(|(v, floor)| format!("{v:.2}{}", if *floor { "†" } else { "" })).collect();
                table_row(
                    &mut md,
                    &[
                        study.scene.name.clone(),
                        b.clone(),
                        integrator.name().to_string(),
                        integrator.order().to_string(),
                        list.join(", "),
                    ],
                );
            }
        }
    }
    let damped = studies.iter().any(|s| {
        s.scene.effects.contains(cloth_core::Effect::SpringDamping)
            || s.scene.effects.contains(cloth_core::Effect::AirDrag)
    });
    if damped {
        let _ = writeln!(
            md,
            "\nWith velocity-dependent forces (spring damping or air drag), velocity Verlet evaluates them \
             with the velocity at hand (the half-step one in its second kick), a first-order error in \
             those terms: its slope falls from 2 towards 1 as the step shrinks and that term takes over."
        );
    }
    let _ = writeln!(
        md,
        "\nXPBD's error is not only the truncation of a first-order method: it models no spring \
         damping, and with {} iterations its springs are softer than `k` at large steps. In f32 its \
         velocities come from position differences, `(x' − x)/Δt`, so the rounding of a position \
         (1.2e-7 m near 1.5 m) becomes a velocity error of about 1.2e-7/Δt m/s in every substep: at \
         small steps the f32 error grows again (a negative slope) while f64 keeps converging. Backward \
         Euler's first-order error is its numerical damping; VBD's adds what its sweeps leave \
         unconverged.",
        cloth_core::integrator::XPBD_ITERATIONS
    );
    let _ = writeln!(
        md,
        "\nThe CI test `crates/cloth-core/tests/convergence.rs` checks every integrator's order \
         within ±0.3 on a smooth undamped scene in f64."
    );

    if studies.iter().any(|s| !s.limits.is_empty()) {
        let _ = writeln!(md, "\n## Largest stable step\n");
        let _ = writeln!(
            md,
            "Bisection over 2000 substeps from the scene's start, on each backend, against two \
             predictions of `cloth_core::stability`: the spectral estimate (`λ_max(M⁻¹K)` by power \
             iteration on the springs' stiffness matrix at rest, damping bounded by Gershgorin) and the \
             safe Gershgorin bound (`ω_max² ≤ 2Σk/m`) that validation and `Auto` substeps use. XPBD, \
             backward Euler and VBD have no limit to predict; they are run at 10, 100 and 1000 times \
             the explicit limit instead, for 200 substeps.\n"
        );
        table_head(
            &mut md,
            &[
                "scene",
                "backend",
                "integrator",
                "spectral (s)",
                "measured (s)",
                "measured / spectral",
                "safe (s)",
                "measured / safe",
            ],
        );
        for study in studies {
            for l in &study.limits {
                let head = format!("| {} | {} | {} |", study.scene.name, l.backend, l.integrator.name());
                let _ = match &l.outcome {
                    Outcome::Measured(h) => writeln!(
                        md,
                        "{head} {} | {} | {:.2} | {} | {:.2} |",
                        sci(l.spectral_s),
                        sci(*h),
                        h / l.spectral_s,
                        sci(l.safe_s),
                        h / l.safe_s
                    ),
                    Outcome::UnstableBelowBracket => {
                        writeln!(md, "{head} {} | unstable at ¼ of it | | {} | |", sci(l.spectral_s), sci(l.safe_s))
                    }
                    Outcome::StableAt(m) => {
                        writeln!(md, "{head} none | stable at {m}× the explicit limit | | none | |")
                    }
                    Outcome::DivergedAt(m) => {
                        writeln!(md, "{head} none | diverged at {m}× the explicit limit | | none | |")
                    }
                    Outcome::Skipped(reason) => writeln!(md, "{head} | skipped: {reason} | | | |"),
                };
            }
        }
        let _ = writeln!(
            md,
            "\nWith damping the spectral prediction is conservative (the damping rate is itself bounded \
             by Gershgorin), most for RK4, whose damped stability region is not the symplectic methods' \
             shape. With contact the penalty springs add to the fastest mode wherever the cloth touches. \
             On an undamped cloth (`crates/cloth-core/tests/stability_limits.rs`, run in CI) the \
             measured limits are held within 20% of the spectral prediction, and XPBD is checked bounded \
             at 1000 times the explicit limit."
        );
    }

    let first = studies.first().map(|s| &s.scene);
    let _ = writeln!(md, "\n## How to read this\n");
    let _ = writeln!(
        md,
        "* **Semi-implicit Euler** (the model's) costs one force evaluation per substep and is first \
         order: halving the step halves the error. **Velocity Verlet** costs two and is second order; \
         **RK4** costs four and is fourth order, but dissipates energy slowly and is not symplectic. \
         All three have a stability limit that stiff springs shrink: ten times fewer substeps on the \
         stiff drape than on the drape.\n\
         * **XPBD** projects each spring as a constraint with compliance `1/k` ({iterations} \
         Gauss–Seidel sweeps per substep, colour by colour). It is stable at any step; it is first \
         order, models no spring damping, and with few iterations the cloth is softer than its \
         springs' `k`.\n\
         * **Backward Euler** solves the implicit-Euler step by Newton's method with preconditioned \
         conjugate gradients (by default two Newton iterations, the first Baraff and Witkin's \
         linearised step, each cut back by a line search where it overshoots). It is stable at any \
         step and first order, and its error is mostly numerical damping: the energy it dissipates \
         grows with the step.\n\
         * **VBD** (Vertex Block Descent) minimises the same implicit-Euler energy by per-vertex Newton \
         steps over five vertex colours, with, by default, a multigrid coarse correction \
         once every {multigrid_every} sweeps that carries the pins' and colliders' hold across the \
         cloth; its error is implicit Euler's plus what its sweeps leave unconverged.\n\
         * On a GPU, each force evaluation, CG iteration or colour sweep is one or more dispatches; \
         XPBD takes {xpbd_dispatches} dispatches per substep on `{name}`. At small grids a dispatch \
         costs a few microseconds whatever it computes, so the GPU cost follows the dispatch count \
         more than the arithmetic.\n\
         * Below about 1e-7 m, f32 stops improving (the rounding of positions near 1.5 m); only f64 \
         keeps converging, which is why the f64 CPU backend reaches budgets the others cannot.\n\
         * For a student: on a smooth, soft cloth small explicit steps win; once springs are stiff or \
         the frame must be one substep, only the methods without a stability limit run at all, and \
         the two-budget tables above say which of them to take for each budget.",
        iterations = cloth_core::integrator::XPBD_ITERATIONS,
        multigrid_every = cloth_core::solver::SolverSpec::default().vbd_multigrid_every,
        xpbd_dispatches = first.map_or(0, xpbd_dispatches),
        name = first.map_or("", |s| s.name.as_str()),
    );

    let _ = writeln!(md, "\n## Every run\n");
    table_head(
        &mut md,
        &[
            "scene",
            "backend",
            "integrator",
            "substeps / frame",
            "Δt (s)",
            "RMS error (m)",
            "max error (m)",
            "energy drift",
            "energy dissipated (J)",
            "max strain",
            "solver iterations / substep",
            "wall ms / sim s",
            "GPU ms / sim s",
        ],
    );
    for study in studies {
        for r in &study.rows {
            let ok = !r.diverged;
            table_row(
                &mut md,
                &[
                    study.scene.name.clone(),
                    r.backend.clone(),
                    r.integrator.name().to_string(),
                    r.substeps.to_string(),
                    format!("{:.2e}", r.dt),
                    if ok { sci(r.rms_error_m) } else { "diverged".into() },
                    if ok { sci(r.max_error_m) } else { String::new() },
                    if ok { sci(r.energy_drift) } else { String::new() },
                    if ok { format!("{:.3}", r.energy_dissipated_j) } else { String::new() },
                    if ok { sci(r.max_strain) } else { String::new() },
                    r.solver_iterations_per_substep.map(|k| format!("{k:.1}")).unwrap_or_else(|| "—".into()),
                    ms(r.wall_ms_per_simulated_s),
                    r.gpu_ms_per_simulated_s.map(ms).unwrap_or_else(|| "—".into()),
                ],
            );
        }
    }
    let _ = writeln!(
        md,
        "\nEnergy drift is (final total energy − the reference's) / |initial total energy|; energy \
         dissipated is the reference's final total energy minus the run's; max strain is the largest \
         |L/L0 − 1| over the springs at the end."
    );
    md
}
