//! Set-up and task runner of the cloth workbench.
//!
//! * `cargo xtask run [ARGS...]`: installs what is missing, then opens the inspector on the
//!   default drape scene; without a display it says so and runs `cloth run`, writing
//!   `out/drape.png`;
//! * `cargo xtask test`: installs what is missing, then runs every check CI runs
//!   (`cargo fmt --check`, `cargo clippy -D warnings`, `cargo test --workspace`);
//! * `cargo xtask setup`: only installs the system packages and the glTF validator (npm).
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

/// Every system package the project needs.
const PACKAGES: &[Package] = &[
    Package { name: "libvulkan1", why: "the Vulkan loader, used by the wgpu backend" },
    Package {
        name: "mesa-vulkan-drivers",
        why: "lavapipe, Mesa's CPU Vulkan driver: GPU tests run on it without a GPU",
    },
    Package { name: "vulkan-tools", why: "vulkaninfo, to print the Vulkan devices before the tests" },
    Package { name: "glslc", why: "compiles the GLSL shaders of the vulkano backend to SPIR-V at build time" },
    Package {
        name: "vulkan-validationlayers",
        why: "the Khronos validation layer: debug test runs of the vulkano backend fail on any message",
    },
    Package { name: "xvfb", why: "a virtual X display: the inspector's screenshot tests run under xvfb-run" },
    Package { name: "xauth", why: "used by xvfb-run" },
    Package { name: "libxkbcommon-x11-0", why: "keyboard handling of the inspector's window (winit)" },
    Package { name: "libx11-xcb1", why: "X11 connection of the inspector's window (winit)" },
    Package { name: "libegl1", why: "EGL, for the inspector's window surface" },
    Package { name: "libegl-mesa0", why: "Mesa's EGL" },
    Package { name: "libgl1-mesa-dri", why: "Mesa's drivers" },
    Package { name: "libgles2", why: "GLES, for eframe's fallback renderer" },
];

fn main() -> Result<()> {
    quiet_xdg_runtime_dir();
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
            eprintln!("  run    install what is missing, then open the inspector (headless: cloth run, out/drape.png)");
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

/// Node.js and npm, unless a `node` and an `npm` are already on the PATH (from Debian or another
/// distribution of Node).
const NODE_PACKAGES: &[Package] = &[
    Package { name: "nodejs", why: "runs the Khronos glTF validator on the export tests' files" },
    Package { name: "npm", why: "installs the glTF validator (tests/gltf-validator)" },
];

fn on_path(command: &str) -> bool {
    Command::new(command).arg("--version").output().is_ok_and(|o| o.status.success())
}

fn setup() -> Result<()> {
    install_packages()?;
    install_validator()
}

/// The npm packages of `tests/gltf-validator` (the Khronos glTF validator), installed from its
/// lock file when missing.
fn install_validator() -> Result<()> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/gltf-validator");
    if dir.join("node_modules/gltf-validator/package.json").is_file() {
        return Ok(());
    }
    eprintln!("xtask: installing the glTF validator (npm ci in tests/gltf-validator)");
    sh(Command::new("npm").args(["ci", "--no-audit", "--no-fund", "--silent"]).current_dir(&dir))
}

fn install_packages() -> Result<()> {
    let mut missing: Vec<&Package> = PACKAGES.iter().filter(|p| !installed(p.name)).collect();
    if !(on_path("node") && on_path("npm")) {
        missing.extend(NODE_PACKAGES.iter().filter(|p| !installed(p.name)));
    }
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
    let has_display = std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some();
    if has_display {
        let mut cmd = cargo();
        cmd.args(["run", "--release", "--quiet", "--package", "cloth-inspector", "--"]);
        if extra.is_empty() {
            cmd.args(["--scene", "scenes/drape.ron"]);
        } else {
            cmd.args(extra);
        }
        return sh(&mut cmd);
    }
    if !extra.is_empty() {
        bail!(
            "no display (DISPLAY and WAYLAND_DISPLAY are unset), so the inspector cannot open a window for `{}`; \
             run it under a virtual display (`xvfb-run -a cargo xtask run {}`), or use the headless \
             `cloth run` (`cargo run --release -p cloth-cli -- run --help`)",
            extra.join(" "),
            extra.join(" ")
        );
    }
    eprintln!(
        "xtask: no display (DISPLAY and WAYLAND_DISPLAY are unset), so the inspector cannot open a window;\n\
         xtask: running the headless `cloth run` instead and writing the picture to out/drape.png"
    );
    std::fs::create_dir_all("out").context("cannot create out/")?;
    let mut cmd = cargo();
    cmd.args(["run", "--release", "--quiet", "--package", "cloth-cli", "--bin", "cloth", "--", "run"]);
    cmd.args(["scenes/drape.ron", "--png", "out/drape.png"]);
    sh(&mut cmd)
}

fn test() -> Result<()> {
    print_devices();
    sh(cargo().args(["fmt", "--all", "--", "--check"])).context("formatting differs: run `cargo fmt --all`")?;
    sh(cargo().args(["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"]))?;
    // Without a GPU the suites run on lavapipe, which by default hands every dispatch to a pool of
    // one thread a core and wakes it. The suites' grids are small and their dispatches many (an
    // implicit substep records hundreds), so the wake-ups cost more than the pool saves, and the
    // second test thread keeps the other core busy: lavapipe runs each dispatch on the calling
    // thread instead. Other Vulkan drivers ignore the variable.
    sh(cargo().args(["test", "--workspace"]).env("RUSTDOCFLAGS", "-D warnings").env("LP_NUM_THREADS", "0"))?;
    sh(cargo().args(["doc", "--no-deps", "--package", "cloth-core"]).env("RUSTDOCFLAGS", "-D warnings"))
}

/// Prints the Vulkan devices the GPU tests will run on (informational; never fails).
fn print_devices() {
    eprintln!("xtask: Vulkan devices (vulkaninfo --summary):");
    match Command::new("vulkaninfo").arg("--summary").output() {
        Ok(out) => {
            let text = String::from_utf8_lossy(&out.stdout);
            for line in text
                .lines()
                .filter(|l| l.contains("deviceName") || l.contains("deviceType") || l.contains("driverInfo"))
            {
                eprintln!("    {}", line.trim());
            }
        }
        Err(e) => eprintln!("    vulkaninfo could not run: {e}"),
    }
}

/// Mesa warns on every device creation when XDG_RUNTIME_DIR is unset or invalid; give it a
/// private directory.
fn quiet_xdg_runtime_dir() {
    let ok = std::env::var_os("XDG_RUNTIME_DIR").map(|d| std::path::Path::new(&d).is_dir()).unwrap_or(false);
    if !ok {
        let dir = std::env::temp_dir().join(format!("cloth-xdg-runtime-{}", std::process::id()));
        if std::fs::create_dir_all(&dir).is_ok() {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
            // SAFETY: called at start-up, before any thread is spawned.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        }
    }
}

fn sh(cmd: &mut Command) -> Result<()> {
    let shown = format!("{cmd:?}");
    let status = cmd.status().with_context(|| format!("cannot start {shown}"))?;
    if !status.success() {
        bail!("{shown} failed with {status}");
    }
    Ok(())
}
