//! Set-up and task runner of the cloth workbench.
//!
//! * `cargo xtask run [ARGS...]`: installs what is missing, then runs the main job
//!   (`cloth run` on the default drape scene, writing `out/drape.png`);
//! * `cargo xtask test`: installs what is missing, then runs every check CI runs
//!   (`cargo fmt --check`, `cargo clippy -D warnings`, `cargo test --workspace`);
//! * `cargo xtask setup`: only installs the system packages.
//!
//! System packages are installed with apt when running as root on Debian/Ubuntu; otherwise the
//! exact command is printed and the task stops.

use std::process::Command;

use anyhow::{Context, Result, bail};

/// A Debian package the project needs, and why.
struct Package {
    name: &'static str,
    why: &'static str,
}

/// Every system package the project needs. Later backends add theirs here.
const PACKAGES: &[Package] = &[];

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (task, rest) = args.split_first().map(|(t, r)| (t.as_str(), r)).unwrap_or(("help", &[]));
    match task {
        "setup" => setup(),
        "run" => {
            setup()?;
            run_main_job(rest)
        }
        "test" => {
            setup()?;
            test()
        }
        _ => {
            eprintln!("usage: cargo xtask <run [ARGS...] | test | setup>");
            eprintln!("  run    install what is missing, then simulate the default drape scene (out/drape.png)");
            eprintln!("  test   install what is missing, then fmt, clippy and every test");
            eprintln!("  setup  install the system packages the project needs");
            if task == "help" { Ok(()) } else { bail!("unknown task '{task}'") }
        }
    }
}

fn installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", package])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("install ok installed"))
        .unwrap_or(false)
}

fn is_root() -> bool {
    Command::new("id").arg("-u").output().map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0").unwrap_or(false)
}

fn setup() -> Result<()> {
    let missing: Vec<&Package> = PACKAGES.iter().filter(|p| !installed(p.name)).collect();
    if missing.is_empty() {
        return Ok(());
    }
    let names: Vec<&str> = missing.iter().map(|p| p.name).collect();
    for p in &missing {
        eprintln!("xtask: missing system package {} ({})", p.name, p.why);
    }
    let command = format!("apt-get update && apt-get install -y --no-install-recommends {}", names.join(" "));
    let has_apt = Command::new("apt-get").arg("--version").output().is_ok();
    if !(is_root() && has_apt) {
        bail!("install the missing packages first, as root:\n    {command}\nthen run this command again");
    }
    eprintln!("xtask: {command}");
    sh(Command::new("apt-get").arg("update").arg("-qq"))?;
    sh(Command::new("apt-get")
        .args(["install", "-y", "-qq", "--no-install-recommends"])
        .args(&names)
        .env("DEBIAN_FRONTEND", "noninteractive"))
}

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn run_main_job(extra: &[String]) -> Result<()> {
    std::fs::create_dir_all("out").context("cannot create out/")?;
    let mut cmd = cargo();
    cmd.args(["run", "--release", "--quiet", "--package", "cloth-cli", "--bin", "cloth", "--", "run"]);
    if extra.is_empty() {
        cmd.args(["scenes/drape.ron", "--png", "out/drape.png"]);
    } else {
        cmd.args(extra);
    }
    sh(&mut cmd)
}

fn test() -> Result<()> {
    sh(cargo().args(["fmt", "--all", "--", "--check"])).context("formatting differs: run `cargo fmt --all`")?;
    sh(cargo().args(["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"]))?;
    sh(cargo().args(["test", "--workspace"]).env("RUSTDOCFLAGS", "-D warnings"))?;
    sh(cargo().args(["doc", "--no-deps", "--package", "cloth-core"]).env("RUSTDOCFLAGS", "-D warnings"))
}

fn sh(cmd: &mut Command) -> Result<()> {
    let shown = format!("{cmd:?}");
    let status = cmd.status().with_context(|| format!("cannot start {shown}"))?;
    if !status.success() {
        bail!("{shown} failed with {status}");
    }
    Ok(())
}
