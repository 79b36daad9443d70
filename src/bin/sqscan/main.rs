//! `sqscan`: the command-line tool of sqscan: simulator, model viewer, cloud inspector, offline
//! detector and evaluator, mock devices and device bring-up, and the daemon's client.

mod client;
mod detect;
mod eval;
mod eval_real;
mod files;
mod learn;
mod mock;
mod ptu;
mod sensor;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "sqscan", version, about = "Find known objects in laser range scans", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// `--models-dir`, on the commands that read models.
#[derive(clap::Args, Clone, Debug)]
pub struct ModelsDirArg {
    /// Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models,
    /// /etc/sqscan/models, /usr/share/sqscan/models that exists]
    #[arg(long = "models-dir", value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

impl ModelsDirArg {
    /// The directory given, or the one the search path finds.
    pub fn dir(&self) -> PathBuf {
        let d = self.dir.clone().unwrap_or_else(sqscan::model::default_models_dir);
        if !d.is_dir() {
            tracing::warn!("{}", sqscan::model::missing_models_dir(&d));
        }
        d
    }
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one sweep of a scene: writes cloud.ply, cloud.pcd, range.png and truth.json
    Simulate(files::SimulateArgs),
    /// Sample a model's surface into a PLY file (one colour a part)
    ShowModel(files::ShowModelArgs),
    /// Print a point cloud file's point count, finite points, organization and bounding box
    Info(files::InfoArgs),
    /// Find an object in a point cloud file; prints one JSON object
    Detect(detect::DetectArgs),
    /// Learn a model by showing the object: recover its superquadric from one scan
    Learn(learn::LearnArgs),
    /// Measure detection rate, false "found" rate, time and pose error on simulated sweeps
    Eval(eval::EvalArgs),
    /// Measure the detector on real scans labelled by object class: recall, false answers, time
    EvalReal(eval_real::EvalRealArgs),
    /// Run mock devices on pseudo-terminals (use their paths like hardware)
    Mock(mock::MockArgs),
    /// Bring-up tool for a pan-tilt unit: status, home, move, sweep
    Ptu(ptu::PtuArgs),
    /// Bring-up tool for a profile sensor: grab profiles and print their statistics
    Sensor(sensor::SensorArgs),
    /// Ask the daemon where an object is (from a recent sweep, or the next one)
    Find(client::FindArgs),
    /// Ask the daemon for a sweep now; prints it when complete
    Scan(client::ScanArgs),
    /// Fetch a recent sweep's points from the daemon into a PCD file
    Cloud(client::CloudArgs),
    /// Print every sweep's detections of the given objects until interrupted
    Watch(client::WatchArgs),
    /// The daemon's devices, last sweep, rates and faults
    Status(client::PlainArgs),
    /// The objects the daemon knows
    Models(client::PlainArgs),
    /// Print a shell completion script for sqscan (or, with --daemon, sqscand)
    Completions(CompletionsArgs),
    /// Write the manual pages of sqscan (one a subcommand) and sqscand into a directory
    #[command(hide = true)]
    Man(ManArgs),
}

#[derive(clap::Args)]
struct CompletionsArgs {
    /// The shell: e.g. `sqscan completions bash > ~/.local/share/bash-completion/completions/sqscan`
    shell: clap_complete::Shell,
    /// The script for sqscand instead of sqscan
    #[arg(long)]
    daemon: bool,
}

#[derive(clap::Args)]
struct ManArgs {
    /// Directory to write sqscan.1, sqscan-*.1 and sqscand.8 into (created if missing)
    #[arg(value_name = "DIR")]
    out: PathBuf,
}

fn completions(a: CompletionsArgs) -> Result<()> {
    use clap::CommandFactory;
    let (mut cmd, name) = if a.daemon {
        (sqscan::daemon::cli::DaemonCli::command(), "sqscand")
    } else {
        (Cli::command(), "sqscan")
    };
    clap_complete::generate(a.shell, &mut cmd, name, &mut std::io::stdout());
    Ok(())
}

fn man(a: ManArgs) -> Result<()> {
    use anyhow::Context;
    use clap::CommandFactory;
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let write = |r: std::io::Result<()>| r.with_context(|| format!("writing manual pages into {}", a.out.display()));
    write(clap_mangen::generate_to(Cli::command(), &a.out))?;
    write(
        clap_mangen::Man::new(sqscan::daemon::cli::DaemonCli::command())
            .section("8")
            .generate_to(&a.out)
            .map(|_| ()),
    )?;
    Ok(())
}

fn main() -> ExitCode {
    // Like every Unix filter: end quietly when the reader of stdout goes away (`sqscan eval ... |
    // head`), instead of panicking in println! on a broken pipe. Rust ignores SIGPIPE by default.
    // SAFETY: restoring a signal's default disposition at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    // Diagnostics go to stderr, so stdout stays one JSON object where a command promises one.
    // SQSCAN_LOG=debug shows, for example, every hypothesis of the detector with its scores.
    sqscan::logging::init(tracing::Level::WARN);
    let result: Result<()> = match cli.command {
        Command::Simulate(a) => {
            let d = a.models.dir();
            files::simulate(a, &d)
        }
        Command::ShowModel(a) => {
            let d = a.models.dir();
            files::show_model(a, &d)
        }
        Command::Info(a) => files::info(a),
        Command::Detect(a) => {
            let d = a.models.dir();
            detect::detect(a, &d)
        }
        Command::Eval(a) => {
            let d = a.models.dir();
            eval::eval(a, &d)
        }
        Command::EvalReal(a) => {
            let d = a.models.dir();
            eval_real::run(a, &d)
        }
        Command::Learn(a) => {
            let d = a.models.dir();
            learn::run(a, &d)
        }
        Command::Mock(a) => mock::run(a),
        Command::Ptu(a) => ptu::run(a),
        Command::Sensor(a) => sensor::run(a),
        Command::Find(a) => client::find(a),
        Command::Scan(a) => client::scan(a),
        Command::Cloud(a) => client::cloud(a),
        Command::Watch(a) => client::watch(a),
        Command::Status(a) => client::status(a),
        Command::Models(a) => client::models(a),
        Command::Completions(a) => completions(a),
        Command::Man(a) => man(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the chain of contexts, outermost first.
            // A file's or a peer's text in the chain is printed with its control characters
            // escaped: no terminal escape sequences.
            eprintln!(
                "sqscan: error: {}",
                sqscan::spec::escape_controls(&format!("{e:#}").replace('\n', " "))
            );
            ExitCode::FAILURE
        }
    }
}

/// Files the tool writes (sweeps, models, detections) go through a temporary file and a rename.
pub use sqscan::atomic::write_atomic;

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    fn has_json(c: &clap::Command) -> bool {
        c.get_arguments().any(|a| a.get_long() == Some("json"))
    }

    /// Every command with its full name (`ptu sweep`), and whether it or a command above it
    /// takes --json (`ptu --json sweep`); clap's generated `help` commands left out.
    fn commands(cmd: &clap::Command, prefix: &str, json_above: bool, out: &mut Vec<(String, clap::Command, bool)>) {
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            let name = format!("{prefix}{}", sub.get_name());
            let json = json_above || has_json(sub);
            out.push((name.clone(), sub.clone(), json));
            commands(sub, &format!("{name} "), json, out);
        }
    }

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
        sqscan::daemon::cli::DaemonCli::command().debug_assert();
    }

    #[test]
    fn every_option_has_help_and_every_command_that_prints_results_has_json() {
        let mut cmd = Cli::command();
        cmd.build();
        let mut all = Vec::new();
        commands(&cmd, "", false, &mut all);
        let mut daemon = sqscan::daemon::cli::DaemonCli::command();
        daemon.build();
        all.push(("sqscand".into(), daemon, false));
        // Commands whose output is JSON only, or not results: device mocks that serve until
        // interrupted, the completion script, the manual pages.
        let no_json_flag = [
            "detect",
            "learn",
            "mock ptu",
            "mock rig",
            "completions",
            "man",
            "sqscand",
        ];
        let mut problems = Vec::new();
        for (name, c, json) in &all {
            for arg in c.get_arguments() {
                let id = arg.get_id().as_str();
                if id == "help" || id == "version" {
                    continue;
                }
                if arg.get_help().is_none_or(|h| h.to_string().trim().is_empty()) {
                    problems.push(format!("`{name}`: `{id}` has no help text"));
                }
            }
            // A command with subcommands prints nothing itself.
            if !c.has_subcommands() && *json == no_json_flag.contains(&name.as_str()) {
                problems.push(format!(
                    "`{name}`: --json {}",
                    if *json { "where it is not expected" } else { "missing" }
                ));
            }
        }
        assert!(problems.is_empty(), "{}", problems.join("\n"));
    }
}
