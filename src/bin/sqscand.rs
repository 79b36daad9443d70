//! `sqscand`: the sqscan daemon. See `docs/DAEMON.md` and `docs/PROTOCOL.md`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Parser;
use sqscan::daemon::cli::DaemonCli as Cli;
use sqscan::daemon::config::{BackendConfig, Config, DEFAULT_CONFIG_PATH};
use sqscan::daemon::{Daemon, notify::Notifier};

fn load_config(cli: &Cli) -> Result<Config> {
    let path = match &cli.config {
        Some(p) => Some(p.clone()),
        None => Some(PathBuf::from(DEFAULT_CONFIG_PATH)).filter(|p| p.exists()),
    };
    let mut config = match &path {
        Some(p) => Config::from_file(p).map_err(|e| anyhow::anyhow!(e.with_causes()))?,
        None => Config::embedded_default(),
    };
    if let Some(s) = &cli.socket {
        config.socket = s.clone();
    }
    if let Some(d) = &cli.models_dir {
        config.models_dir = d.clone();
    }
    if let Some(dir) = &cli.replay {
        let (lo, hi) = sqscan::daemon::config::limits::REPLAY_SPEED;
        if !(cli.replay_speed.is_finite() && (lo..=hi).contains(&cli.replay_speed)) {
            anyhow::bail!("--replay-speed {}: give a factor from {lo} to {hi}", cli.replay_speed);
        }
        config.backend = BackendConfig::Replay {
            dir: dir.clone(),
            speed: if cli.replay_step { 0.0 } else { cli.replay_speed },
            looping: cli.replay_loop,
        };
        if cli.replay_step {
            config.continuous = false;
        }
    }
    Ok(config)
}

fn describe(config: &Config) -> String {
    let source = match &config.source {
        Some(p) => p.display().to_string(),
        None => "the embedded default (no config file)".into(),
    };
    let backend = match &config.backend {
        BackendConfig::Sim { scene, .. } => format!("the simulated scanner on {}", scene.display()),
        BackendConfig::Hardware(h) => format!("the PTU at {} and the sensor at {}", h.ptu_path.display(), h.sensor),
        BackendConfig::Replay { dir, speed, .. } if *speed == 0.0 => {
            format!("the recorded sweeps in {}, as fast as asked", dir.display())
        }
        BackendConfig::Replay { dir, speed, .. } => {
            format!("the recorded sweeps in {} at {speed} times their pace", dir.display())
        }
    };
    format!("configuration from {source}; scanning with {backend}")
}

async fn run(cli: &Cli, config: Config) -> Result<()> {
    let notifier = Notifier::from_env();
    tracing::info!("{}", describe(&config));
    let tcp = config.tcp;
    let socket = config.socket.clone();
    // The handlers before start-up: READY=1 goes out from inside it, and a reload (or a stop)
    // asked for at once must not find the signals' default action, which ends the process.
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate()).context("cannot install the SIGTERM handler")?;
    let mut int = signal(SignalKind::interrupt()).context("cannot install the SIGINT handler")?;
    let mut hup = signal(SignalKind::hangup()).context("cannot install the SIGHUP handler")?;
    let daemon = Daemon::start(config, notifier).await?;
    // Where to ask, on stderr (the journal under systemd), whatever the log level.
    eprintln!(
        "sqscand: listening on {}{}; try `sqscan find cup --socket {}`",
        socket.display(),
        tcp.map(|a| format!(" and tcp {a}")).unwrap_or_default(),
        socket.display()
    );
    let failure = loop {
        tokio::select! {
            _ = int.recv() => break None,
            _ = term.recv() => break None,
            // Re-read the configuration and the models; a refused reload is logged and shown
            // in `status`, and the daemon runs on as before.
            _ = hup.recv() => {
                tracing::info!("SIGHUP: reloading");
                let _ = daemon.reload(|| load_config(cli));
            }
            // A dead acquisition or server task: exit with an error, which systemd restarts.
            f = daemon.failed() => break Some(f),
        }
    };
    tracing::info!("stopping");
    daemon.stop().await;
    match failure {
        Some(f) => anyhow::bail!("{f}"),
        None => Ok(()),
    }
}

fn main() -> ExitCode {
    sqscan::daemon::memory::tune_allocator();
    let cli = Cli::parse();
    sqscan::logging::init(tracing::Level::INFO);
    let result = load_config(&cli).and_then(|config| {
        if cli.check {
            let models = sqscan::daemon::check(&config)?;
            println!(
                "{}; {} models in {}",
                describe(&config),
                models.len(),
                config.models_dir.display()
            );
            if cli.probe {
                let rt = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .context("cannot start the runtime")?;
                for line in rt.block_on(sqscan::daemon::probe(&config))? {
                    println!("{line}");
                }
            }
            return Ok(());
        }
        let rt = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("sqscand")
            .build()
            .context("cannot start the runtime")?;
        let r = rt.block_on(run(&cli, config));
        // Detections still on the blocking pool are abandoned: stopping must take < 2 s.
        rt.shutdown_timeout(Duration::from_millis(200));
        r
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A file's or a peer's text in the chain is printed with its control characters
            // escaped: no terminal escape sequences.
            eprintln!(
                "sqscand: error: {}",
                sqscan::spec::escape_controls(&format!("{e:#}").replace('\n', " "))
            );
            ExitCode::FAILURE
        }
    }
}
