//! Daemon figures for BENCHMARKS.md: sweep-to-answer latency (last profile in to detection out)
//! and answers per second with 200 clients.
//!
//! `cargo bench --bench daemon [-- SWEEPS SECONDS]` (defaults 10 sweeps, 10 s). Runs the mock rig
//! (PowerCube + sensor on ptys, Fig. 3 scene, 50 profiles/s) and the daemon in this process, as
//! the daemon would run on hardware; clients talk to it over its Unix socket from OS threads.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use sqscan::daemon::Daemon;
use sqscan::daemon::config::Config;
use sqscan::mock::rig::{RigConfig, RigMock};
use sqscan::sim::Scene;
use sqscan_drivers::PtuKind;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

struct Client {
    r: BufReader<UnixStream>,
    w: UnixStream,
}

impl Client {
    fn connect(socket: &Path) -> Client {
        let s = UnixStream::connect(socket).expect("connect");
        let w = s.try_clone().unwrap();
        let mut c = Client {
            r: BufReader::new(s),
            w,
        };
        let _version = c.read();
        c
    }
    fn read(&mut self) -> Value {
        let mut line = String::new();
        self.r.read_line(&mut line).unwrap();
        serde_json::from_str(&line).unwrap()
    }
    fn ask(&mut self, v: &Value) -> Value {
        self.w.write_all(format!("{v}\n").as_bytes()).unwrap();
        self.read()
    }
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let sweeps: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(10);
    let seconds: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(10.0);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let dir = std::env::temp_dir().join(format!("sqscan-bench-daemon-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models")).unwrap();
    let (ptu, sensor) = (dir.join("ptu"), dir.join("sensor"));
    let _rig = rt.block_on(async {
        RigMock::start(
            Arc::new(scene),
            &RigConfig {
                ptu_kind: PtuKind::PowerCube,
                ..RigConfig::default()
            },
            Some(&ptu),
            Some(&sensor),
        )
        .unwrap()
    });
    let socket = dir.join("sqscand.sock");
    let config = format!(
        r#"
[server]
socket = "{}"
[hardware]
calibration = "{}"
ptu = {{ path = "{}", protocol = "powercube" }}
sensor = {{ path = "{}" }}
[sweep]
tilt_from_rad = 0.49
tilt_to_rad = 0.84
speed_rad_s = 0.12
"#,
        socket.display(),
        root().join("calibration/sim_rig.toml").display(),
        ptu.display(),
        sensor.display()
    );
    let config = Config::from_toml_str(&config, &dir.join("sqscand.toml")).unwrap();
    let daemon = rt.block_on(Daemon::start(config, None)).unwrap();

    latency(&socket, sweeps);
    throughput(&socket, seconds);
    rt.block_on(daemon.stop());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Latency: a watcher sees every sweep's cup detection; latency_ms runs from the sweep's last
/// profile to the detection's end.
fn latency(socket: &Path, sweeps: usize) {
    let mut c = Client::connect(socket);
    let r = c.ask(&json!({"cmd":"watch","objects":["cup"]}));
    assert_eq!(r["class"], "watch", "{r}");
    let mut latency = Vec::new();
    let mut run = Vec::new();
    let mut found = 0;
    while latency.len() < sweeps {
        let r = c.read();
        if r["class"] != "detection" || r["sweep"]["age_s"].as_f64().unwrap_or(1.0) > 0.5 {
            continue; // the greeting's answer from an older sweep
        }
        latency.push(r["latency_ms"].as_f64().unwrap());
        run.push(r["timing_ms"]["total"].as_f64().unwrap());
        found += usize::from(r["found"] == true);
        eprintln!("sweep {}: latency {:.1} ms", r["sweep"]["id"], r["latency_ms"]);
    }
    drop(c);
    println!(
        "sweep-to-answer latency over {sweeps} sweeps (cup found in {found}): median {:.1} ms, p95 {:.1} ms, max {:.1} ms; detection alone median {:.1} ms",
        percentile(&mut latency.clone(), 0.5),
        percentile(&mut latency.clone(), 0.95),
        percentile(&mut latency, 1.0),
        percentile(&mut run, 0.5)
    );
}

/// Throughput: 200 clients asking "find cup" (or bowl) back to back for `seconds`.
fn throughput(socket: &Path, seconds: f64) {
    let answers = Arc::new(AtomicU64::new(0));
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let mut times: Vec<f64> = Vec::new();
    let t0 = Instant::now();
    let handles: Vec<_> = (0..200)
        .map(|i| {
            let (socket, answers) = (socket.to_path_buf(), answers.clone());
            std::thread::spawn(move || {
                let mut c = Client::connect(&socket);
                let object = ["cup", "bowl"][i % 2];
                let req = json!({"cmd":"find","object":object,"max_age_s":10.0,"timeout_s":30});
                let mut t = Vec::new();
                while Instant::now() < deadline {
                    let s = Instant::now();
                    let r = c.ask(&req);
                    assert_eq!(r["class"], "detection", "{r}");
                    t.push(s.elapsed().as_secs_f64() * 1e3);
                    answers.fetch_add(1, Ordering::Relaxed);
                }
                t
            })
        })
        .collect();
    for h in handles {
        times.extend(h.join().unwrap());
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let n = answers.load(Ordering::Relaxed);
    println!(
        "200 clients, {seconds:.0} s: {n} answers, {:.0} answers/s; per request median {:.2} ms, p95 {:.2} ms",
        n as f64 / elapsed,
        percentile(&mut times.clone(), 0.5),
        percentile(&mut times, 0.95)
    );
}
