//! What gets installed: the shell completions and manual pages in `dist/` are what the binaries
//! generate now, and the Debian package (`cargo deb`) holds every file where the unit, the
//! sysusers entry, the shipped configuration and the client expect it, and passes lintian.
//!
//! The package test needs `cargo deb` (crates.io cargo-deb), `dpkg-deb` and `lintian`; without
//! them it says it skipped, unless `SQSCAN_REQUIRE_PACKAGE_TOOLS` is set (the README's test
//! command sets it, after installing them). Regenerate `dist/` after changing a command line
//! with `SQSCAN_BLESS=1 cargo test --test package`.

mod architecture;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SQSCAN: &str = env!("CARGO_BIN_EXE_sqscan");

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?}: {}\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Every file under `dir`, by path relative to it, with its bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        out.insert(
            p.file_name().unwrap().to_string_lossy().into_owned(),
            std::fs::read(&p).unwrap(),
        );
    }
    out
}

#[test]
fn completions_and_manual_pages_in_dist_are_current() {
    let bless = std::env::var_os("SQSCAN_BLESS").is_some();
    let dist = root().join("dist");
    let mut stale = Vec::new();
    for shell in ["bash", "zsh", "fish"] {
        for (daemon, name) in [(false, "sqscan"), (true, "sqscand")] {
            let mut cmd = Command::new(SQSCAN);
            cmd.args(["completions", shell]);
            if daemon {
                cmd.arg("--daemon");
            }
            let generated = run(&mut cmd).stdout;
            assert!(String::from_utf8_lossy(&generated).contains(name), "{name} {shell}");
            let path = dist.join(format!("completions/{name}.{shell}"));
            if bless {
                std::fs::write(&path, &generated).unwrap();
            }
            if std::fs::read(&path).ok().as_deref() != Some(&generated[..]) {
                stale.push(path.display().to_string());
            }
        }
    }
    let tmp = std::env::temp_dir().join(format!("sqscan-man-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    run(Command::new(SQSCAN).arg("man").arg(&tmp));
    let generated = files(&tmp);
    for page in [
        "sqscan.1",
        "sqscand.8",
        "sqscan-find.1",
        "sqscan-mock-rig.1",
        "sqscan-ptu-sweep.1",
    ] {
        assert!(generated.contains_key(page), "no {page}: {:?}", generated.keys());
    }
    let man = dist.join("man");
    if bless {
        let _ = std::fs::remove_dir_all(&man);
        std::fs::create_dir_all(&man).unwrap();
        for (name, bytes) in &generated {
            std::fs::write(man.join(name), bytes).unwrap();
        }
    }
    if files(&man) != generated {
        stale.push(man.display().to_string());
    }
    let _ = std::fs::remove_dir_all(&tmp);
    assert!(
        stale.is_empty(),
        "{stale:?} differ from what sqscan generates: regenerate with SQSCAN_BLESS=1 cargo test --test package"
    );
}

/// Whether `program --version` runs.
fn have(program: &[&str]) -> bool {
    Command::new(program[0])
        .args(&program[1..])
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// `key=value` lines of a unit or a config, first value of each key.
fn unit_value<'a>(unit: &'a str, key: &str) -> &'a str {
    unit.lines()
        .find_map(|l| l.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("no {key}= in the unit"))
}

#[test]
fn the_debian_package_installs_every_file_where_it_is_expected_and_passes_lintian() {
    let tools = [vec!["cargo", "deb"], vec!["dpkg-deb"], vec!["lintian"]];
    if let Some(missing) = tools.iter().find(|t| !have(t)) {
        assert!(
            std::env::var_os("SQSCAN_REQUIRE_PACKAGE_TOOLS").is_none(),
            "{} is missing, and SQSCAN_REQUIRE_PACKAGE_TOOLS is set",
            missing.join(" ")
        );
        let _ = writeln!(
            std::io::stderr(),
            "the_debian_package_...: skipped: `{}` is not installed (scripts/test.sh installs cargo-deb and lintian)",
            missing.join(" ")
        );
        return;
    }
    let scratch = std::env::temp_dir().join(format!("sqscan-deb-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch).unwrap();
    run(Command::new("cargo")
        .current_dir(root())
        .args(["deb", "--locked", "--output"])
        .arg(&scratch));
    let deb = std::fs::read_dir(&scratch)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with("sqscan_") && n.ends_with(".deb")
        })
        .expect("cargo deb made no sqscan_*.deb");

    // The control data: name, dependencies, the conffile, the user created on install.
    let info = String::from_utf8(run(Command::new("dpkg-deb").arg("-I").arg(&deb)).stdout).unwrap();
    assert!(info.contains("Package: sqscan\n"), "{info}");
    assert!(info.contains("Depends: libc6"), "{info}");
    let field =
        |f: &str| String::from_utf8(run(Command::new("dpkg-deb").args(["-f"]).arg(&deb).arg(f)).stdout).unwrap();
    let arch = String::from_utf8(run(Command::new("dpkg").arg("--print-architecture")).stdout).unwrap();
    assert_eq!(field("Architecture").trim(), arch.trim());
    let control = scratch.join("control");
    run(Command::new("dpkg-deb").arg("-e").arg(&deb).arg(&control));
    let conffiles = std::fs::read_to_string(control.join("conffiles")).unwrap();
    assert_eq!(conffiles.trim(), "/etc/sqscan/sqscand.toml");
    let postinst = std::fs::read_to_string(control.join("postinst")).unwrap();
    assert!(
        postinst.contains("systemd-sysusers") && postinst.contains("sqscan.conf"),
        "{postinst}"
    );
    let listing = String::from_utf8(run(Command::new("dpkg-deb").arg("-c").arg(&deb)).stdout).unwrap();
    for path in [
        "./usr/bin/sqscan",
        "./usr/bin/sqscand",
        "./usr/lib/systemd/system/sqscand.service",
        "./usr/lib/sysusers.d/sqscan.conf",
        "./etc/sqscan/sqscand.toml",
        "./usr/share/man/man8/sqscand.8.gz",
        "./usr/share/man/man1/sqscan.1.gz",
        "./usr/share/bash-completion/completions/sqscan",
        "./usr/share/doc/sqscan/copyright",
    ] {
        assert!(listing.contains(&format!(" {path}\n")), "no {path} in:\n{listing}");
    }

    // lintian: no errors (it exits non-zero on one).
    let lint = Command::new("lintian").arg(&deb).output().unwrap();
    let text = String::from_utf8_lossy(&lint.stdout).into_owned() + &String::from_utf8_lossy(&lint.stderr);
    assert!(
        lint.status.success() && !text.lines().any(|l| l.starts_with("E:")),
        "lintian: {text}"
    );

    // Unpacked: every file where the unit, the sysusers entry, the configuration and the client
    // look for it.
    let fs = scratch.join("root");
    run(Command::new("dpkg").arg("-x").arg(&deb).arg(&fs));
    let at = |p: &str| fs.join(p.trim_start_matches('/'));
    let unit = std::fs::read_to_string(at("/usr/lib/systemd/system/sqscand.service")).unwrap();
    let exec: Vec<&str> = unit_value(&unit, "ExecStart").split_whitespace().collect();
    assert_eq!(exec[0], "/usr/bin/sqscand");
    use std::os::unix::fs::PermissionsExt;
    assert!(std::fs::metadata(at(exec[0])).unwrap().permissions().mode() & 0o111 != 0);
    let config_path = exec[exec.iter().position(|a| *a == "--config").unwrap() + 1];
    assert!(
        at(config_path).is_file(),
        "the unit's --config {config_path} is not in the package"
    );
    for doc in unit_value(&unit, "Documentation").split_whitespace() {
        if let Some(p) = doc.strip_prefix("file:") {
            assert!(at(p).is_file(), "Documentation={doc} is not in the package");
        }
        if let Some(page) = doc.strip_prefix("man:") {
            let (name, section) = page.trim_end_matches(')').split_once('(').unwrap();
            assert!(
                at(&format!("/usr/share/man/man{section}/{name}.{section}.gz")).is_file(),
                "{doc}"
            );
        }
    }
    // The unit's user is the one the sysusers entry creates, with the state directory as home.
    let sysusers = std::fs::read_to_string(at("/usr/lib/sysusers.d/sqscan.conf")).unwrap();
    let user_line: Vec<&str> = sysusers
        .lines()
        .find(|l| l.starts_with("u "))
        .unwrap()
        .split_whitespace()
        .collect();
    assert_eq!(user_line[1], unit_value(&unit, "User"));
    assert_eq!(
        *user_line.last().unwrap(),
        format!("/var/lib/{}", unit_value(&unit, "StateDirectory"))
    );
    assert!(
        sysusers
            .lines()
            .any(|l| l.split_whitespace().collect::<Vec<_>>() == ["m", "sqscan", "dialout"])
    );

    // The shipped configuration, read as the daemon reads it: its socket is in the unit's
    // RuntimeDirectory and where the client looks; its recordings under the StateDirectory; its
    // calibration in the package.
    let config_text = std::fs::read_to_string(at(config_path)).unwrap();
    let config: toml::Table = toml::from_str(&config_text).unwrap();
    let socket = config["server"]["socket"].as_str().unwrap();
    assert_eq!(
        Path::new(socket).parent().unwrap(),
        Path::new("/run").join(unit_value(&unit, "RuntimeDirectory"))
    );
    assert!(sqscan::daemon::config::client_socket_candidates().contains(&PathBuf::from(socket)));
    let record = config["record"]["dir"].as_str().unwrap();
    assert!(
        record.starts_with(&format!("/var/lib/{}/", unit_value(&unit, "StateDirectory"))),
        "{record}"
    );
    let calibration = config["hardware"]["calibration"].as_str().unwrap();
    assert!(
        at(calibration).is_file(),
        "calibration {calibration} is not in the package"
    );
    // Its models: the package's directory is on the search path, and every model loads.
    assert!(sqscan::model::MODELS_SEARCH_PATH.contains(&"/usr/share/sqscan/models"));
    assert!(
        config["server"].get("models_dir").is_none(),
        "the shipped config should use the search path"
    );
    let models = sqscan::daemon::load_models(&at("/usr/share/sqscan/models")).unwrap();
    assert!(
        models.contains_key("cup") && models.contains_key("mallet"),
        "{:?}",
        models.keys()
    );
    // The embedded default's scene, for `sqscand` run without a configuration.
    assert!(at("/usr/share/sqscan/scenes/fig3_table.toml").is_file());
    // The PTU's URDF, for a robot's own robot_state_publisher (docs/ROS2.md).
    assert!(at("/usr/share/sqscan/urdf/sqscan_ptu.urdf").is_file());

    // The packaged daemon checks the packaged configuration, paths moved into the scratch root.
    let moved = config_text.replace("/usr/share/sqscan", at("/usr/share/sqscan").to_str().unwrap());
    let moved_path = scratch.join("sqscand.toml");
    std::fs::write(&moved_path, moved).unwrap();
    let check = Command::new(at("/usr/bin/sqscand"))
        .arg("--config")
        .arg(&moved_path)
        .arg("--models-dir")
        .arg(at("/usr/share/sqscan/models"))
        .arg("--check")
        .env_remove("NOTIFY_SOCKET")
        .output()
        .unwrap();
    assert!(
        check.status.success(),
        "the packaged sqscand --check on the packaged configuration: {}",
        String::from_utf8_lossy(&check.stderr)
    );
    let _ = std::fs::remove_dir_all(&scratch);
}
