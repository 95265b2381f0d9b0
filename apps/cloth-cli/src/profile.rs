//! `cloth profile`: where a GPU frame's time goes, pass by pass. Each profiled frame is recorded
//! with a timestamp before its first dispatch and after each (`Simulator::profile_frame`), and the
//! table sums the dispatches of each pipeline over the frames: how many a frame records, their
//! GPU time a frame, the mean, shortest and longest time a dispatch, and their share of the
//! frame. A rebuild pass of self-collision shows both of its kinds: its longest dispatches
//! rebuild, its shortest run empty.
//!
//! A diagnostic, not a benchmark: each profiled frame waits for the device, and a timestamp after
//! every dispatch can hold the next one back, so the passes may add up to a little more than the
//! frame takes unprofiled (`cloth bench` times that).

use anyhow::{Result, bail};
use cloth_core::budget::WorkPlan;
use cloth_core::{PassTime, Scene, Substeps};

use crate::{load_scene, parse_grid, parse_substeps};
use cloth_backends as backends;

/// Options of `cloth profile`.
#[derive(clap::Args)]
pub struct ProfileArgs {
    /// RON scene file (default: the built-in drape scene, as in scenes/drape.ron).
    scene: Option<std::path::PathBuf>,
    /// GPU backend to profile: wgpu or vulkano.
    #[arg(long, default_value = "wgpu")]
    backend: String,
    /// Frames simulated, unprofiled, before the profiled ones: where in the scene to look.
    #[arg(long, default_value_t = 0)]
    skip: u32,
    /// Frames profiled, at least 1; the table gives their mean.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    frames: u32,
    /// Grid resolution NXxNY, e.g. 256x256 (vertices along each side).
    #[arg(long, value_parser = parse_grid)]
    grid: Option<[u32; 2]>,
    /// Substeps per frame (a number, or `auto`).
    #[arg(long, value_parser = parse_substeps)]
    substeps: Option<Substeps>,
    /// Also write the table to this CSV file.
    #[arg(long)]
    csv: Option<std::path::PathBuf>,
    #[command(flatten)]
    tuning: crate::tuning::TuningArgs,
}

/// What `cloth profile` will run, decided before anything runs.
pub(crate) struct Plan {
    scene: Scene,
    backend: backends::Backend,
    /// Checked against the budgets when planned; the property test reads it back.
    #[cfg_attr(not(test), expect(dead_code, reason = "the run needs only the check"))]
    pub(crate) work: WorkPlan,
}

/// The plan of `args`.
///
/// # Errors
/// An unknown or CPU backend, an invalid scene, or frames beyond the backend's budget.
pub(crate) fn plan(args: &ProfileArgs) -> Result<Plan> {
    let backend = backends::find(&args.backend).map_err(anyhow::Error::msg)?;
    // Only the GPU backends have a device whose bandwidth can be probed.
    if backend.copy_bandwidth.is_none() {
        bail!("--backend {}: a profile times a GPU frame's passes; profile wgpu or vulkano", backend.name);
    }
    let scene = load_scene(args.scene.as_ref(), args.grid, args.substeps)?;
    let mut work = WorkPlan::default();
    let frames =
        args.skip.checked_add(args.frames).ok_or_else(|| anyhow::anyhow!("--skip plus --frames is too many"))?;
    work.add(backend.name, &scene, frames).map_err(|p| anyhow::anyhow!("--{p}"))?;
    Ok(Plan { scene, backend, work })
}

pub(crate) fn run(args: ProfileArgs) -> Result<()> {
    let Plan { scene, backend, .. } = plan(&args)?;
    if let Some(path) = &args.csv {
        cloth_backends::output::check_writable(path)?;
    }
    let mut sim = (backend.create)(&scene, &args.tuning.tuning())?;
    let [nx, ny] = scene.cloth.resolution;
    out!(
        "profile    {} on {}: {nx}x{ny} grid, {} substeps a frame, frames {} to {}",
        backend.name,
        sim.adapter_name(),
        scene.substeps_per_frame(),
        args.skip + 1,
        args.skip + args.frames
    )?;
    if args.skip > 0 {
        sim.advance(args.skip)?;
    }
    let lists_before = sim.diagnostics()?.candidate_lists;
    let mut total: Vec<PassTime> = Vec::new();
    for _ in 0..args.frames {
        let Some(frame) = sim.profile_frame()? else {
            bail!("{} cannot write timestamps between dispatches on {}: no profile", backend.name, sim.adapter_name());
        };
        frame.into_iter().for_each(|pass| pass.add_to(&mut total));
    }
    let frames = args.frames as f64;
    let frame_s: f64 = total.iter().map(|p| p.seconds).sum::<f64>() / frames;
    out!(
        "{:<36} {:>10} {:>10} {:>12} {:>9} {:>9} {:>6}",
        "pass",
        "dispatches",
        "ms",
        "us/dispatch",
        "shortest",
        "longest",
        "share"
    )?;
    let mut csv = String::from(
        "backend,adapter,nx,ny,substeps,first_frame,frames,pass,dispatches_per_frame,ms_per_frame,us_per_dispatch,\
         us_shortest,us_longest\n",
    );
    for p in &total {
        let per_frame = p.dispatches as f64 / frames;
        let (ms, us) = (p.seconds / frames * 1e3, p.seconds / p.dispatches as f64 * 1e6);
        let (shortest, longest) = (p.shortest_s * 1e6, p.longest_s * 1e6);
        let share = 100.0 * p.seconds / frames / frame_s;
        out!("{:<36} {per_frame:>10.2} {ms:>10.4} {us:>12.2} {shortest:>9.2} {longest:>9.2} {share:>5.1}%", p.name)?;
        csv += &format!(
            "{},\"{}\",{nx},{ny},{},{},{},\"{}\",{per_frame},{ms},{us},{shortest},{longest}\n",
            backend.name,
            sim.adapter_name().replace('"', "'"),
            scene.substeps_per_frame(),
            args.skip + 1,
            args.frames,
            p.name.replace('"', "'")
        );
    }
    let dispatches: u32 = total.iter().map(|p| p.dispatches).sum();
    out!("{:<36} {:>10.2} {:>10.4}", "frame", dispatches as f64 / frames, frame_s * 1e3)?;
    if let (Some(before), Some(after)) = (lists_before, sim.diagnostics()?.candidate_lists) {
        out!(
            "self-collision: {} of the {} checks rebuilt the lists (the others' rebuild passes ran empty)",
            after.rebuilds - before.rebuilds,
            after.checks - before.checks
        )?;
    }
    if let Some(path) = &args.csv {
        cloth_backends::output::write_atomically(path, csv.as_bytes())?;
        out!("wrote {}", path.display())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_backends_have_no_passes_to_profile() {
        use clap::Parser as _;
        let cli = crate::Cli::try_parse_from(["cloth", "profile", "--backend", "cpu"]).expect("parses");
        let crate::Command::Profile(args) = cli.command else { unreachable!() };
        let message = plan(&args).err().expect("refused").to_string();
        assert!(message.contains("profile wgpu or vulkano"), "{message}");
    }
}
