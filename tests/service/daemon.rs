//! End to end: the `sqscand` binary as a separate process, asked over its Unix socket as a
//! client on the robot would, on the embedded simulator and on mock devices on ptys (the mock rig
//! as a separate `sqscan mock rig` process, so the daemon opens them exactly like hardware).
//!
//! Over 600 lines on purpose: every test here shares the daemon process harness at the top
//! (spawn, socket, JSON-lines client, readiness), which is the point of one file.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixDatagram, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};
use serde_json::{Value, json};
use sqscan::eval::{Symmetry, truth_pose};
use sqscan::model::Model;
use sqscan::sim::Scene;

use crate::common::protocol::check_reply;
use crate::common::{Proc, free_port, tmpdir, wait_for};

/// Starts `sqscand --config` on `config` text written into `dir`; returns once the socket
/// answers.
fn start_daemon(dir: &Path, config: &str, env: &[(&str, &str)]) -> (Proc, PathBuf) {
    start_daemon_with(dir, config, env, |_| {})
}

/// [`start_daemon`], with `adjust` given the command before it is spawned.
fn start_daemon_with(
    dir: &Path,
    config: &str,
    env: &[(&str, &str)],
    adjust: impl FnOnce(&mut Command),
) -> (Proc, PathBuf) {
    let cfg = dir.join("sqscand.toml");
    std::fs::write(&cfg, config).unwrap();
    let socket = dir.join("sqscand.sock");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_sqscand"));
    cmd.arg("--config")
        .arg(&cfg)
        .arg("--socket")
        .arg(&socket)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("sqscand.log")).unwrap())
        .env_remove("NOTIFY_SOCKET")
        .env_remove("WATCHDOG_USEC")
        // The models, unless the configuration names its own directory.
        .env("SQSCAN_MODELS_DIR", root().join("models"));
    for (k, v) in env {
        cmd.env(k, v);
    }
    adjust(&mut cmd);
    let child = Proc(cmd.spawn().unwrap());
    wait_for("the daemon's socket", Duration::from_secs(30), || {
        UnixStream::connect(&socket).is_ok()
    });
    (child, socket)
}

fn log(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("sqscand.log")).unwrap_or_default()
}

struct Client {
    r: BufReader<UnixStream>,
    w: UnixStream,
}

impl Client {
    fn connect(socket: &Path) -> Client {
        let s = UnixStream::connect(socket).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(90))).unwrap();
        let w = s.try_clone().unwrap();
        let mut c = Client {
            r: BufReader::new(s),
            w,
        };
        let hello = c.read();
        assert_eq!(hello["class"], "version", "{hello}");
        assert_eq!(hello["proto_major"], sqscan::daemon::reply::PROTO_MAJOR);
        c
    }
    fn send_raw(&mut self, bytes: &[u8]) {
        self.w.write_all(bytes).unwrap();
    }
    fn send(&mut self, v: &Value) {
        self.send_raw(format!("{v}\n").as_bytes());
    }
    /// The next message, checked against the protocol's schema and types.
    fn read(&mut self) -> Value {
        let mut line = String::new();
        let n = self.r.read_line(&mut line).unwrap();
        assert!(n > 0, "the daemon closed the connection");
        let v = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"));
        check_reply(&v);
        v
    }
    fn ask(&mut self, v: Value) -> Value {
        self.send(&v);
        self.read()
    }
}

fn v3(v: &Value) -> Vector3<f64> {
    Vector3::new(v[0].as_f64().unwrap(), v[1].as_f64().unwrap(), v[2].as_f64().unwrap())
}

/// The detection's pose against the scene's truth: (position error m, rotation error deg modulo
/// the model's symmetries).
fn pose_error(reply: &Value, scene: &Path, object: &str) -> (f64, f64) {
    let scene = Scene::from_file(scene, &root().join("models")).unwrap();
    let model = Model::load(object, &root().join("models")).unwrap();
    let (_, truth) = truth_pose(&scene, &model).unwrap();
    let pose = &reply["pose"];
    let p = v3(&pose["position"]);
    let q = &pose["orientation"];
    let q = UnitQuaternion::from_quaternion(Quaternion::new(
        q[3].as_f64().unwrap(),
        q[0].as_f64().unwrap(),
        q[1].as_f64().unwrap(),
        q[2].as_f64().unwrap(),
    ));
    let dp = (Point3::from(p) - Point3::from(truth.translation.vector)).norm();
    let dr = Symmetry::of(&model).rotation_error(&q, &truth.rotation).to_degrees();
    (dp, dr)
}

const SIM_FAST: &str = r#"
[sim]
scene = "SCENE"
seed = 3
realtime = false
[sweep]
pause_s = 0.3
"#;

fn sim_config() -> String {
    SIM_FAST.replace("SCENE", root().join("scenes/fig3_table.toml").to_str().unwrap())
}

#[test]
fn simulated_backend_finds_the_cup_and_answers_every_request() {
    let dir = tmpdir("sim");
    let (_d, socket) = start_daemon(&dir, &sim_config(), &[]);
    let mut c = Client::connect(&socket);

    let r = c.ask(json!({"cmd":"find","object":"cup","max_age_s":2.0,"timeout_s":30,"id":"q1"}));
    assert_eq!(r["class"], "detection", "{r}");
    assert_eq!(r["id"], "q1");
    assert_eq!(r["found"], true, "{r}");
    assert!(r["sweep"]["id"].as_u64().unwrap() >= 1);
    let (dp, dr) = pose_error(&r, &root().join("scenes/fig3_table.toml"), "cup");
    assert!(dp < 0.010 && dr < 10.0, "cup off by {dp} m, {dr} deg: {r}");
    // Reported standing up (z along the table normal), not upside down.
    let q = &r["pose"]["orientation"];
    let q = UnitQuaternion::from_quaternion(Quaternion::new(
        q[3].as_f64().unwrap(),
        q[0].as_f64().unwrap(),
        q[1].as_f64().unwrap(),
        q[2].as_f64().unwrap(),
    ));
    assert!((q * Vector3::z()).z > 0.95, "{r}");
    assert!(r.get("grasps").is_none(), "grasps only when asked: {r}");

    // Grasps when asked: the gripper's pads on either side of the cup, the pre-grasp pose back
    // along the approach, farther from the cup.
    let r = c.ask(json!({"cmd":"find","object":"cup","grasps":2}));
    let grasps = r["grasps"].as_array().unwrap_or_else(|| panic!("no grasps: {r}"));
    assert!((1..=2).contains(&grasps.len()), "{r}");
    let cup: Vec<f64> = (0..3).map(|k| r["pose"]["position"][k].as_f64().unwrap()).collect();
    let dist = |p: &serde_json::Value| {
        (0..3)
            .map(|k| (p[k].as_f64().unwrap() - cup[k]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    for g in grasps {
        let opening = g["opening_m"].as_f64().unwrap();
        assert!(opening > 0.03 && opening < 0.085, "{g}");
        assert!(dist(&g["pose"]["position"]) < 0.05, "{g}");
        assert!(
            dist(&g["pregrasp"]["position"]) > dist(&g["pose"]["position"]) + 0.05,
            "{g}"
        );
    }

    // Not there: a clear "not found", not the most similar thing. The mug's nearest lookalike is
    // the scene's cup, a closed cylinder of nearly its size, which is what a mug on its rim shows
    // but for the raised middle of a mug's base.
    for object in ["book", "mug"] {
        let r = c.ask(json!({"cmd":"find","object":object,"timeout_s":30}));
        assert_eq!(r["class"], "detection", "{r}");
        assert_eq!(r["found"], false, "{object}: {r}");
    }

    // Bad requests get errors naming what was wrong, and the connection keeps serving.
    let r = c.ask(json!({"cmd":"find","object":"teapot"}));
    assert_eq!(
        (&r["class"], &r["code"]),
        (&json!("error"), &json!("unknown_object")),
        "{r}"
    );
    assert!(
        r["message"].as_str().unwrap().contains("unknown object \"teapot\""),
        "{r}"
    );
    c.send_raw(b"{\"cmd\": \"find\", \"object\n");
    let r = c.read();
    assert_eq!(
        (&r["class"], &r["code"]),
        (&json!("error"), &json!("bad_request")),
        "{r}"
    );
    assert!(r["message"].as_str().unwrap().contains("malformed JSON"), "{r}");
    c.send_raw(b"\x00\xff garbage \x01\n");
    assert_eq!(c.read()["class"], "error");
    let mut big = vec![b'x'; 100 * 1024];
    big.push(b'\n');
    c.send_raw(&big);
    let r = c.read();
    assert_eq!(r["code"], "too_large", "{r}");
    assert!(r["message"].as_str().unwrap().contains("over the limit"), "{r}");
    let r = c.ask(json!({"cmd":"status"}));
    assert_eq!(r["class"], "status", "{r}");
    assert_eq!(r["devices"][0]["state"], "ok", "{r}");
    assert!(r["sweeps"]["completed"].as_u64().unwrap() >= 1);
    let r = c.ask(json!({"cmd":"models"}));
    assert!(
        r["models"].as_array().unwrap().iter().any(|m| m["name"] == "cup"),
        "{r}"
    );

    // scan: a sweep begun after the request. The request's id and the sweep's number are
    // both there (protocol 1 let the one overwrite the other).
    let before = c.ask(json!({"cmd":"status"}))["last_sweep"]["id"].as_u64().unwrap_or(0);
    let r = c.ask(json!({"cmd":"scan","timeout_s":30,"id":"q1"}));
    assert_eq!((&r["class"], &r["id"]), (&json!("sweep"), &json!("q1")), "{r}");
    assert!(r["sweep"]["id"].as_u64().unwrap() > before, "{r}");
    assert!(r["sweep"]["points"].as_u64().unwrap() > 30_000, "{r}");

    // watch: one detection a sweep for each object, from successive sweeps.
    let r = c.ask(json!({"cmd":"watch","objects":["bowl","cup"]}));
    assert_eq!(r["class"], "watch", "{r}");
    let mut seen: Vec<(u64, String)> = Vec::new();
    while seen.len() < 6 {
        let r = c.read();
        assert_eq!(r["class"], "detection", "{r}");
        assert_eq!(r["found"], true, "{r}");
        seen.push((
            r["sweep"]["id"].as_u64().unwrap(),
            r["object"].as_str().unwrap().to_string(),
        ));
    }
    let sweeps: std::collections::BTreeSet<u64> = seen.iter().map(|s| s.0).collect();
    assert!(sweeps.len() >= 3, "{seen:?}");
    assert!(seen.iter().any(|s| s.1 == "bowl") && seen.iter().any(|s| s.1 == "cup"));
}

#[test]
fn two_hundred_clients_at_once_each_get_their_answer() {
    let dir = tmpdir("many");
    let (_d, socket) = start_daemon(&dir, &sim_config(), &[]);
    // Wait for a first sweep so the rush is answered from it (and from the next ones).
    let mut c = Client::connect(&socket);
    assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":30}))["class"], "sweep");
    let t0 = Instant::now();
    let handles: Vec<_> = (0..200)
        .map(|i| {
            let socket = socket.clone();
            std::thread::spawn(move || {
                let mut c = Client::connect(&socket);
                let object = ["cup", "bowl"][i % 2];
                let r = c.ask(json!({"cmd":"find","object":object,"max_age_s":5.0,"timeout_s":60,"id":i}));
                (i, r)
            })
        })
        .collect();
    for h in handles {
        let (i, r) = h.join().unwrap();
        assert_eq!(r["class"], "detection", "client {i}: {r}");
        assert_eq!(r["id"], i, "{r}");
        assert_eq!(r["found"], true, "client {i}: {r}");
    }
    let secs = t0.elapsed().as_secs_f64();
    eprintln!("200 clients answered in {secs:.2} s");
    let s = c.ask(json!({"cmd":"status"}));
    assert!(s["clients"]["total"].as_u64().unwrap() >= 201, "{s}");
}

/// An idle client, and one that sends a byte a second without ever finishing a line (a
/// slowloris), are closed after the idle timeout, with a line that says why; a client with a
/// watch is not idle.
#[test]
fn idle_and_slowloris_clients_are_closed_after_the_idle_timeout() {
    let dir = tmpdir("idle");
    let config = format!("{}\n[server]\nidle_timeout_s = 1.0\n", sim_config());
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut idle = Client::connect(&socket);
    let mut slow = Client::connect(&socket);
    let mut watcher = Client::connect(&socket);
    assert_eq!(watcher.ask(json!({"cmd":"watch","objects":["cup"]}))["class"], "watch");
    let t0 = Instant::now();
    let sender = std::thread::spawn(move || {
        for b in br#"{"cmd":"status""# {
            if slow.w.write_all(&[*b]).is_err() {
                break;
            }
            std::thread::sleep(Duration::from_millis(300));
        }
        slow
    });
    let bye = idle.read();
    assert_eq!(
        (&bye["class"], &bye["code"]),
        (&json!("error"), &json!("idle")),
        "{bye}"
    );
    assert!(bye["message"].as_str().unwrap().contains("idle"), "{bye}");
    let waited = t0.elapsed();
    assert!(
        waited >= Duration::from_millis(900) && waited < Duration::from_secs(20),
        "{waited:?}"
    );
    let mut slow = sender.join().unwrap();
    let bye = slow.read();
    assert!(bye["message"].as_str().unwrap().contains("idle"), "{bye}");
    // The watcher still gets its updates.
    for _ in 0..3 {
        let u = watcher.read();
        assert_eq!(u["class"], "detection", "{u}");
    }
}

/// Clients that ask for sweeps' points and never read them hold at most four clouds in the
/// daemon's memory, and cannot keep them from an honest client: 50 that never read anything
/// (each asking 64 clouds) take no slot at all, so the honest client's clouds come at once
/// (before, one was refused as busy at 5 s and again at 30 s); four that read their greeting,
/// ask a cloud each and stop reading take the four slots, and lose them within seconds once the
/// honest client waits for one. Other requests are answered meanwhile.
#[test]
fn clients_that_ask_for_clouds_and_never_read_cannot_starve_an_honest_one() {
    let limit = crate::common::raise_open_files();
    let dir = tmpdir("clouds");
    let (_d, socket) = start_daemon(&dir, &sim_config(), &[]);
    let mut c = Client::connect(&socket);
    assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":30}))["class"], "sweep");
    // The bound shows where a cloud is larger than a socket's send buffer: then a client that
    // does not read keeps its cloud in the daemon.
    let first = c.ask(json!({"cmd":"cloud","max_age_s":3600}));
    let size = first["bytes"].as_u64().unwrap() as usize;
    let mut payload = vec![0u8; size];
    std::io::Read::read_exact(&mut c.r, &mut payload).unwrap();
    let wmem: usize = std::fs::read_to_string("/proc/sys/net/core/wmem_default")
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(212_992);
    if size <= 2 * wmem || limit < 256 {
        let _ = writeln!(
            std::io::stderr(),
            "clients_that_ask_for_clouds_...: skipped: a cloud of {size} bytes fits this host's socket buffers \
             ({wmem}), or only {limit} files may be open"
        );
        return;
    }
    let fetch = |c: &mut Client, timeout: f64| {
        let t = Instant::now();
        let r = c.ask(json!({"cmd":"cloud","max_age_s":3600,"timeout_s":timeout}));
        assert_eq!(r["class"], "cloud", "{r}");
        let mut payload = vec![0u8; r["bytes"].as_u64().unwrap() as usize];
        std::io::Read::read_exact(&mut c.r, &mut payload).unwrap();
        assert!(payload.starts_with(b"# .PCD"), "{:?}", &payload[..16]);
        t.elapsed()
    };
    let silent: Vec<UnixStream> = (0..50)
        .map(|_| {
            let mut s = UnixStream::connect(&socket).unwrap();
            s.write_all("{\"cmd\":\"cloud\",\"max_age_s\":3600}\n".repeat(64).as_bytes())
                .unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    for _ in 0..2 {
        let took = fetch(&mut c, 5.0);
        assert!(
            took < Duration::from_secs(3),
            "the honest cloud took {took:?} beside 50 silent clients"
        );
        assert_eq!(c.ask(json!({"cmd":"status"}))["class"], "status");
        std::thread::sleep(Duration::from_secs(2));
    }
    // Four that read their greeting, then ask and stall: they hold the four slots.
    let stalled: Vec<Client> = (0..4)
        .map(|_| {
            let mut s = Client::connect(&socket);
            writeln!(s.w, "{{\"cmd\":\"cloud\",\"max_age_s\":3600}}").unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    let took = fetch(&mut c, 10.0);
    assert!(
        took < Duration::from_secs(6),
        "the honest cloud took {took:?} beside 4 stalled transfers"
    );
    drop((silent, stalled));
}

/// With every slot taken by idle clients, a new client is answered: the longest-idle one is
/// closed to make room. With every slot taken by busy clients (watching), it is told so.
#[test]
fn idle_clients_cannot_lock_out_a_new_one() {
    let dir = tmpdir("full");
    let config = format!("{}\n[server]\nmax_clients = 8\n", sim_config());
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut first = Client::connect(&socket);
    let rest: Vec<Client> = (0..7).map(|_| Client::connect(&socket)).collect();
    let mut new = Client::connect(&socket);
    assert_eq!(new.ask(json!({"cmd":"status"}))["class"], "status");
    // The first to go idle made room.
    let bye = first.read();
    assert_eq!(bye["code"], "idle", "{bye}");
    assert!(bye["message"].as_str().unwrap().contains("needs the slot"), "{bye}");
    drop(rest);
    // Eight watchers are not idle: a ninth client is refused with a reason.
    let watchers: Vec<Client> = (0..8)
        .map(|_| {
            let mut c = Client::connect(&socket);
            assert_eq!(c.ask(json!({"cmd":"watch","objects":["cup"]}))["class"], "watch");
            c
        })
        .collect();
    drop(new);
    std::thread::sleep(Duration::from_millis(200));
    let s = UnixStream::connect(&socket).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut line = String::new();
    BufReader::new(s).read_line(&mut line).unwrap();
    let busy: Value = serde_json::from_str(&line).unwrap();
    check_reply(&busy);
    assert_eq!(busy["code"], "busy", "{busy}");
    assert!(line.contains("too many clients"), "{line}");
    drop(watchers);
}

#[test]
fn systemd_hears_ready_watchdog_and_a_clean_stop() {
    let dir = tmpdir("notify");
    let notify_path = dir.join("notify.sock");
    let sock = UnixDatagram::bind(&notify_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let (mut d, socket) = start_daemon(
        &dir,
        &sim_config(),
        &[
            ("NOTIFY_SOCKET", notify_path.to_str().unwrap()),
            ("WATCHDOG_USEC", "400000"),
        ],
    );
    let mut got: Vec<String> = Vec::new();
    let mut buf = [0u8; 4096];
    let t0 = Instant::now();
    while !(got.iter().any(|m| m == "READY=1")
        && got.iter().filter(|m| *m == "WATCHDOG=1").count() >= 2
        && got.iter().any(|m| m.starts_with("STATUS=sweep")))
    {
        assert!(t0.elapsed() < Duration::from_secs(30), "{got:?}");
        let n = sock.recv(&mut buf).unwrap();
        got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
    }
    // SIGTERM: gone within 2 s, STOPPING=1 sent, socket removed, a client told why.
    let mut c = Client::connect(&socket);
    let t = Instant::now();
    unsafe_kill(d.0.id(), 15);
    let bye = c.read();
    assert_eq!(
        (&bye["class"], &bye["code"]),
        (&json!("error"), &json!("stopping")),
        "{bye}"
    );
    let status = loop {
        if let Some(s) = d.0.try_wait().unwrap() {
            break s;
        }
        assert!(t.elapsed() < Duration::from_secs(2), "still running 2 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}: {}", log(&dir));
    assert!(!socket.exists());
    sock.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
    let mut stopping = false;
    while let Ok(n) = sock.recv(&mut buf) {
        stopping |= &buf[..n] == b"STOPPING=1";
    }
    assert!(stopping, "{got:?}");
}

/// CI once saw a client's connection closed at SIGTERM without the "stopping" line: the clients'
/// tasks were detached, so the process could exit before they wrote it. Every client, idle or
/// with a request in flight, hears why.
#[test]
fn sigterm_tells_every_connected_client_why_before_exiting() {
    let dir = tmpdir("goodbye");
    let (mut d, socket) = start_daemon(&dir, &sim_config(), &[]);
    let mut clients: Vec<Client> = (0..24).map(|_| Client::connect(&socket)).collect();
    // Half of them wait on a find that the shutdown cuts short.
    for (i, c) in clients.iter_mut().enumerate().filter(|(i, _)| i % 2 == 0) {
        c.send(&json!({"cmd":"find","object":"cup","max_age_s":0.0,"timeout_s":30,"id":i}));
    }
    unsafe_kill(d.0.id(), 15);
    for (i, c) in clients.iter_mut().enumerate() {
        // A reply that beat the signal may come first; the goodbye must follow it.
        let bye = loop {
            let m = c.read();
            if m["code"] == "stopping" {
                break m;
            }
            assert_ne!(m["class"], "error", "client {i}: {m}");
        };
        assert_eq!(bye["class"], "error", "client {i}: {bye}");
    }
    exits_cleanly_within(&mut d, &dir, Duration::from_secs(5));
}

/// The stop waits for each client's goodbye, but not for a client that does not read: clients
/// that asked for clouds and never read them (their writers stuck on full sockets, for up to 10 s
/// each) do not hold the daemon up past its stop bound.
#[test]
fn clients_that_never_read_do_not_hold_up_a_stop() {
    let dir = tmpdir("stuckstop");
    let (mut d, socket) = start_daemon(&dir, &sim_config(), &[]);
    let mut c = Client::connect(&socket);
    assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":30}))["class"], "sweep");
    let silent: Vec<UnixStream> = (0..6)
        .map(|_| {
            let mut s = UnixStream::connect(&socket).unwrap();
            for _ in 0..3 {
                s.write_all(b"{\"cmd\":\"cloud\",\"max_age_s\":3600}\n").unwrap();
            }
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    unsafe_kill(d.0.id(), 15);
    // The daemon's bound is 1.5 s; the margin is for a loaded machine.
    exits_cleanly_within(&mut d, &dir, Duration::from_secs(5));
    assert!(!socket.exists());
    drop(silent);
}

/// A sweep completed just before SIGTERM is still recorded: the recording was a detached task,
/// which the process's exit could cut short (most often with MCAP, whose recording first waits
/// for the watched objects' detections).
#[test]
fn a_sweep_completed_just_before_sigterm_is_still_recorded() {
    let mcap = if cfg!(feature = "mcap") {
        "mcap = true\n[watch]\nobjects = [\"cup\"]\n"
    } else {
        ""
    };
    for round in 0..3 {
        let dir = tmpdir(&format!("lastrec{round}"));
        let config = format!(
            "{}\n[acquisition]\nmode = \"on_demand\"\n[record]\ndir = \"rec\"\n{mcap}",
            sim_config()
        );
        let (mut d, socket) = start_daemon(&dir, &config, &[]);
        let mut c = Client::connect(&socket);
        let s = c.ask(json!({"cmd":"scan","timeout_s":30}));
        assert_eq!(s["class"], "sweep", "{s}");
        let id = s["sweep"]["id"].as_u64().unwrap();
        unsafe_kill(d.0.id(), 15);
        exits_cleanly_within(&mut d, &dir, Duration::from_secs(5));
        let stem = format!("sweep-{id:08}");
        let rec = dir.join("rec");
        let exts: &[&str] = if mcap.is_empty() {
            &["pcd", "json"]
        } else {
            &["pcd", "json", "mcap"]
        };
        for ext in exts {
            assert!(
                rec.join(format!("{stem}.{ext}")).exists(),
                "round {round}: no {stem}.{ext}: {}",
                log(&dir)
            );
        }
    }
}

/// A thousand clients each sending 200 `models` requests and never reading took the daemon to
/// 937 MB: each held its queue of 64 replies and 64 more in flight. A client's queue is now
/// bounded in bytes and its next request is not read while it is full, so they cost a bounded
/// share each, and an honest client is answered meanwhile.
#[test]
fn a_thousand_clients_that_never_read_their_replies_cost_bounded_memory() {
    let limit = crate::common::raise_open_files();
    if limit < 1200 {
        eprintln!("SKIPPED: this process may open {limit} files, fewer than the 1,000 clients need");
        return;
    }
    let dir = tmpdir("nonreaders");
    let config = format!("{}\n[server]\nmax_clients = 1100\n", sim_config());
    let (d, socket) = start_daemon(&dir, &config, &[]);
    let pid = d.0.id();
    let base = crate::common::rss(pid);
    let requests = "{\"cmd\":\"models\"}\n".repeat(200);
    let mut clients = Vec::new();
    let mut peak = base;
    for k in 0..1000 {
        let mut c = UnixStream::connect(&socket).unwrap();
        c.write_all(requests.as_bytes()).unwrap();
        clients.push(c);
        if k % 50 == 0 {
            peak = peak.max(crate::common::rss(pid));
        }
    }
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(5) {
        peak = peak.max(crate::common::rss(pid));
        std::thread::sleep(Duration::from_millis(100));
    }
    let t = Instant::now();
    let status = Client::connect(&socket).ask(json!({"cmd":"status"}));
    assert_eq!(status["class"], "status", "{status}");
    assert!(t.elapsed() < Duration::from_secs(5), "status took {:?}", t.elapsed());
    eprintln!("RSS {} MB at start, peak {} MB", base >> 20, peak >> 20);
    // About 100 MB here: 4x that.
    assert!(peak < 400 << 20, "peak RSS {} MB from {} MB", peak >> 20, base >> 20);
    drop(clients);
}

/// Under systemd's default file limit (1024, soft and hard), 1,024 idle clients and 200 that
/// send half a request each left a `find` unanswered for 20 s while accept failed for lack of
/// descriptors 448 times and no idle client was closed. The daemon's slots now leave it
/// descriptors of its own, a new client closes the longest-idle one, and a failed accept does
/// too (with one warning in 10 s): the `find` is answered.
#[test]
fn a_thousand_idle_and_two_hundred_slowloris_clients_under_a_1024_file_limit_do_not_lock_out_find() {
    use std::os::unix::process::CommandExt;
    let limit = crate::common::raise_open_files();
    if limit < 1400 {
        eprintln!("SKIPPED: this process may open {limit} files, fewer than the 1,224 clients need");
        return;
    }
    let dir = tmpdir("fdlimit");
    let (_d, socket) = start_daemon_with(&dir, &sim_config(), &[], |cmd| {
        // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                let r = libc::rlimit {
                    rlim_cur: 1024,
                    rlim_max: 1024,
                };
                if libc::setrlimit(libc::RLIMIT_NOFILE, &r) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    });
    let mut clients = Vec::new();
    for k in 0..1224 {
        let Ok(mut c) = UnixStream::connect(&socket) else {
            continue;
        };
        if k >= 1024 {
            let _ = c.write_all(b"{\"cmd\":\"sta");
        }
        clients.push(c);
    }
    let t = Instant::now();
    let found = crate::common::ask(&socket, json!({"cmd":"find","object":"cup","timeout_s":30}));
    assert_eq!(found["class"], "detection", "{found}\n{}", log(&dir));
    assert!(t.elapsed() < Duration::from_secs(20), "find took {:?}", t.elapsed());
    let warnings = log(&dir).matches("accept on").count();
    assert!(warnings <= 5, "{warnings} accept warnings: {}", log(&dir));
    drop(clients);
}

/// A recording whose last file could not be written (a full disk) left its PCD behind without
/// the JSON, and the loss was not counted. A directory where the JSON (or, with MCAP, the MCAP)
/// must go makes that file fail here: the sweep's other files are removed, the loss is a fault
/// and counted in `status`, and the next sweep is recorded whole.
#[test]
fn a_recording_that_cannot_be_completed_leaves_no_part_and_is_a_fault() {
    let mcap = if cfg!(feature = "mcap") {
        "mcap = true\n[watch]\nobjects = [\"cup\"]\n"
    } else {
        ""
    };
    let dir = tmpdir("partrec");
    let rec = dir.join("rec");
    let blocked = if mcap.is_empty() { "json" } else { "mcap" };
    std::fs::create_dir_all(rec.join(format!("sweep-00000001.{blocked}"))).unwrap();
    let config = format!(
        "{}\n[acquisition]\nmode = \"on_demand\"\n[record]\ndir = \"rec\"\n{mcap}",
        sim_config()
    );
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut c = Client::connect(&socket);
    for _ in 0..2 {
        assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":30}))["class"], "sweep");
    }
    wait_for("the second recording", Duration::from_secs(30), || {
        rec.join("sweep-00000002.json").is_file()
    });
    let status = c.ask(json!({"cmd":"status"}));
    assert_eq!(status["sweeps"]["not_recorded"], 1, "{status}\n{}", log(&dir));
    let faults = status["faults"].to_string();
    assert!(faults.contains("sweep 1 not recorded"), "{status}");
    assert!(log(&dir).contains("sweep 1 not recorded"), "{}", log(&dir));
    let mut left: Vec<String> = std::fs::read_dir(&rec)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        // (The bag's metadata may be being rewritten after the second sweep.)
        .filter(|n| (n.contains("00000001") || n.starts_with('.')) && !n.contains("metadata.yaml"))
        .collect();
    left.sort();
    assert_eq!(
        left,
        [format!("sweep-00000001.{blocked}")],
        "only the blocking directory is left"
    );
    let exts: &[&str] = if mcap.is_empty() { &["pcd"] } else { &["pcd", "mcap"] };
    for ext in exts {
        assert!(
            rec.join(format!("sweep-00000002.{ext}")).is_file(),
            "no sweep-00000002.{ext}"
        );
    }
}

/// SIGHUP re-reads the configuration and the models while clients stay connected (a watcher
/// keeps its updates); a broken configuration, or one naming an unknown object, is refused and
/// the old one stays in use; a setting that needs a restart keeps its old value; systemd hears
/// RELOADING=1 then READY=1 each time.
#[test]
fn sighup_reloads_models_and_configuration_without_dropping_clients() {
    let dir = tmpdir("reload");
    let models = dir.join("models");
    std::fs::create_dir_all(&models).unwrap();
    // Every model but the mouse (the scene names many of the rest).
    for e in std::fs::read_dir(root().join("models")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") && !p.ends_with("mouse.toml") {
            std::fs::copy(&p, models.join(p.file_name().unwrap())).unwrap();
        }
    }
    let notify_path = dir.join("notify.sock");
    let sock = UnixDatagram::bind(&notify_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let config = |extra: &str| format!("{}\n[server]\nmodels_dir = \"models\"\n{extra}", sim_config());
    let (d, socket) = start_daemon(&dir, &config(""), &[("NOTIFY_SOCKET", notify_path.to_str().unwrap())]);
    let mut buf = [0u8; 4096];
    let mut next_message = || {
        let n = sock.recv(&mut buf).unwrap();
        String::from_utf8_lossy(&buf[..n]).into_owned()
    };
    // Skip to READY=1; a reload's messages follow it.
    while next_message() != "READY=1" {}
    let awaited_reload = |next_message: &mut dyn FnMut() -> String| {
        let mut seen = Vec::new();
        loop {
            let m = next_message();
            if m.starts_with("STATUS=") {
                continue;
            }
            seen.push(m.clone());
            if m == "READY=1" {
                break;
            }
        }
        assert!(
            seen.len() == 2 && seen[0].starts_with("RELOADING=1\nMONOTONIC_USEC="),
            "{seen:?}"
        );
    };
    let mut c = Client::connect(&socket);
    let mut watcher = Client::connect(&socket);
    assert_eq!(watcher.ask(json!({"cmd":"watch","object":"cup"}))["class"], "watch");
    let names = |c: &mut Client| -> Vec<String> {
        let r = c.ask(json!({"cmd":"models"}));
        r["models"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["name"].as_str().unwrap().to_string())
            .collect()
    };
    let before = names(&mut c);
    assert!(
        before.contains(&"cup".to_string()) && !before.contains(&"mouse".to_string()),
        "{before:?}"
    );
    let r = c.ask(json!({"cmd":"find","object":"mouse"}));
    assert_eq!(r["code"], "unknown_object", "{r}");

    // A new model, a watch list, and two changes that need a restart.
    std::fs::copy(root().join("models/mouse.toml"), models.join("mouse.toml")).unwrap();
    let reloaded = "frame_id = \"table\"\nmax_clients = 7\n[watch]\nobjects = [\"bowl\"]\n";
    std::fs::write(dir.join("sqscand.toml"), config(reloaded)).unwrap();
    unsafe_kill(d.0.id(), libc::SIGHUP);
    awaited_reload(&mut next_message);
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["config"]["reloads"], 1, "{s}");
    assert!(s["config"]["reload_error"].is_null(), "{s}");
    assert_eq!(s["watched"], json!(["bowl", "cup"]), "{s}");
    assert_eq!(names(&mut c).len(), before.len() + 1);
    let r = c.ask(json!({"cmd":"find","object":"mouse","max_age_s":0.0,"timeout_s":30}));
    assert_eq!(
        (&r["class"], &r["frame"]),
        (&json!("detection"), &json!("base_link")),
        "{r}"
    );
    for kept in [
        "server.max_clients changed",
        "server.frame_id (it names the calibration's base frame) changed",
    ] {
        assert!(log(&dir).contains(kept), "{kept}: {}", log(&dir));
    }
    // The watcher was not dropped: its updates go on.
    for _ in 0..2 {
        let u = watcher.read();
        assert_eq!((&u["class"], &u["object"]), (&json!("detection"), &json!("cup")), "{u}");
    }

    // Broken files are refused, and the running configuration stays: a syntax error, a watch
    // list naming no model, and a models directory without the model a client watches.
    std::fs::rename(models.join("cup.toml"), dir.join("cup.toml")).unwrap();
    for (broken, says) in [
        ("idle_timeout_s = \"soon\"\n", "idle_timeout_s"),
        ("[watch]\nobjects = [\"teapot\"]\n", "teapot"),
        ("", "which a client watches"),
    ] {
        std::fs::write(dir.join("sqscand.toml"), config(broken)).unwrap();
        unsafe_kill(d.0.id(), libc::SIGHUP);
        awaited_reload(&mut next_message);
        let s = c.ask(json!({"cmd":"status"}));
        assert_eq!(s["config"]["reloads"], 1, "{s}");
        assert!(s["config"]["reload_error"].as_str().unwrap().contains(says), "{s}");
        let r = c.ask(json!({"cmd":"find","object":"mouse","timeout_s":30}));
        assert_eq!(r["class"], "detection", "{r}");
        assert_eq!(c.ask(json!({"cmd":"status"}))["watched"], json!(["bowl", "cup"]));
    }
    let u = watcher.read();
    assert_eq!((&u["class"], &u["object"]), (&json!("detection"), &json!("cup")), "{u}");
    assert_eq!(c.ask(json!({"cmd":"status"}))["clients"]["connected"], 2);
}

/// The configuration replaced by a FIFO before a SIGHUP: the reload blocked in open(2), waiting
/// for a writer, and the SIGTERM after it was never acted on. Now the reload is refused by name
/// (the running configuration stays), `find` is answered, and SIGTERM stops the daemon; and
/// `sqscand --check` with a FIFO among the models ends, naming it.
#[test]
fn a_configuration_replaced_by_a_fifo_is_refused_on_sighup_and_sigterm_still_stops_the_daemon() {
    let dir = tmpdir("fifo-config");
    let (mut d, socket) = start_daemon(&dir, &sim_config(), &[]);
    let cfg = dir.join("sqscand.toml");
    std::fs::remove_file(&cfg).unwrap();
    let made = Command::new("mkfifo").arg(&cfg).output().unwrap();
    assert!(
        made.status.success(),
        "mkfifo: {}",
        String::from_utf8_lossy(&made.stderr)
    );
    unsafe_kill(d.0.id(), libc::SIGHUP);
    let mut c = Client::connect(&socket);
    let t = Instant::now();
    let s = loop {
        let s = c.ask(json!({"cmd":"status"}));
        if !s["config"]["reload_error"].is_null() {
            break s;
        }
        assert!(t.elapsed() < Duration::from_secs(10), "no reload error after 10 s: {s}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let e = s["config"]["reload_error"].as_str().unwrap();
    assert!(e.contains("sqscand.toml") && e.contains("not a regular file"), "{e}");
    assert_eq!(s["config"]["reloads"], 0, "{s}");
    let r = c.ask(json!({"cmd":"find","object":"cup","timeout_s":30}));
    assert_eq!(r["class"], "detection", "{r}");
    drop(c);
    unsafe_kill(d.0.id(), libc::SIGTERM);
    exits_cleanly_within(&mut d, &dir, Duration::from_secs(5));

    let models = dir.join("models");
    std::fs::create_dir_all(&models).unwrap();
    std::fs::copy(root().join("models/cup.toml"), models.join("cup.toml")).unwrap();
    let made = Command::new("mkfifo").arg(models.join("stuck.toml")).output().unwrap();
    assert!(made.status.success());
    let checked = dir.join("checked.toml");
    std::fs::write(
        &checked,
        format!("{}\n[server]\nmodels_dir = \"models\"\n", sim_config()),
    )
    .unwrap();
    let mut check = Command::new(env!("CARGO_BIN_EXE_sqscand"))
        .arg("--config")
        .arg(&checked)
        .arg("--check")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while check.try_wait().unwrap().is_none() {
        if t.elapsed() > Duration::from_secs(10) {
            let _ = check.kill();
            panic!("sqscand --check still running after 10 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = check.wait_with_output().unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        said.contains("stuck.toml") && said.contains("not a regular file"),
        "{said}"
    );
}

/// Waits for the daemon to exit after a signal, at most `within`, and asserts it exited cleanly.
fn exits_cleanly_within(d: &mut Proc, dir: &Path, within: Duration) {
    let t = Instant::now();
    let status = loop {
        if let Some(s) = d.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            t.elapsed() < within,
            "still running {} s after the signal: {}",
            within.as_secs_f64(),
            log(dir)
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}: {}", log(dir));
}

fn unsafe_kill(pid: u32, sig: i32) {
    // SAFETY: kill(2) on our own child's pid.
    let r = unsafe { libc::kill(pid as i32, sig) };
    assert_eq!(r, 0);
}

/// `sqscan mock rig` in its own process; returns once both links exist.
fn start_rig(dir: &Path, extra: &[&str]) -> (Proc, PathBuf, PathBuf) {
    start_rig_with(dir, "powercube", extra)
}

fn start_rig_with(dir: &Path, protocol: &str, extra: &[&str]) -> (Proc, PathBuf, PathBuf) {
    crate::common::mock_rig(dir, protocol, extra)
}

fn hardware_config(ptu: &Path, sensor: &Path) -> String {
    hardware_config_with(ptu, sensor, "powercube", "sim_rig.toml", 0.84)
}

fn hardware_config_with(ptu: &Path, sensor: &Path, protocol: &str, calibration: &str, tilt_to: f64) -> String {
    crate::common::rig_config(ptu, sensor, protocol, calibration, tilt_to)
}

#[test]
fn mock_devices_on_ptys_find_the_cup() {
    let dir = tmpdir("rig");
    let (_rig, ptu, sensor) = start_rig(&dir, &[]);
    let (_d, socket) = start_daemon(&dir, &hardware_config(&ptu, &sensor), &[]);
    let mut c = Client::connect(&socket);
    let r = c.ask(json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(r["class"], "detection", "{r}\n{}", log(&dir));
    assert_eq!(r["found"], true, "{r}");
    let (dp, dr) = pose_error(&r, &root().join("scenes/fig3_table.toml"), "cup");
    assert!(dp < 0.010 && dr < 10.0, "cup off by {dp} m, {dr} deg: {r}");
    let s = c.ask(json!({"cmd":"status"}));
    let devices = s["devices"].as_array().unwrap();
    assert!(devices.iter().all(|d| d["state"] == "ok"), "{s}");
    let scan = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert_eq!(scan["sweep"]["report"]["profile_times"], "profile", "{scan}");
}

/// `sqscand --check --probe` opens the rig's devices and says what they report, without moving
/// the unit; with the sensor gone it fails naming it.
#[test]
fn check_probe_reports_the_rigs_devices() {
    let dir = tmpdir("probe");
    let (rig, ptu, sensor) = start_rig(&dir, &[]);
    std::fs::write(dir.join("sqscand.toml"), hardware_config(&ptu, &sensor)).unwrap();
    let probe = || {
        Command::new(env!("CARGO_BIN_EXE_sqscand"))
            .arg("--config")
            .arg(dir.join("sqscand.toml"))
            .args(["--check", "--probe"])
            .env("SQSCAN_MODELS_DIR", root().join("models"))
            .stdin(Stdio::null())
            .output()
            .unwrap()
    };
    let out = probe();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}{}", String::from_utf8_lossy(&out.stderr));
    let ptu_line = text
        .lines()
        .find(|l| l.starts_with("ptu "))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        ptu_line.contains("PowerCube") && ptu_line.contains("limits pan ["),
        "{ptu_line}"
    );
    let sensor_line = text
        .lines()
        .find(|l| l.starts_with("sensor "))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(sensor_line.contains("SQPF profiles of 256 columns"), "{sensor_line}");
    assert!(!sensor_line.contains("calibration has"), "{sensor_line}");
    drop(rig);
    wait_for("the rig to go", Duration::from_secs(10), || !sensor.exists());
    let out = probe();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("ptu "), "{err}");
}

#[test]
fn a_flir_ptu_d46_rig_finds_the_cup() {
    // A PTU-D46 tilts down at negative positions (tilt range -47..+31 deg): mounted with tilt
    // sign -1, the sweep 0.49..0.80 rad down is -0.49..-0.80 rad on the unit. The FLIR driver at
    // 9600 baud, its ASCII protocol and the sign in the calibration all take part.
    let dir = tmpdir("flir");
    let (_rig, ptu, sensor) = start_rig_with(&dir, "flir", &["--tilt-sign", "-1"]);
    let config = hardware_config_with(&ptu, &sensor, "flir", "sim_rig_flir.toml", 0.80);
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut c = Client::connect(&socket);
    let r = c.ask(json!({"cmd":"find","object":"cup","timeout_s":90}));
    assert_eq!(r["class"], "detection", "{r}\n{}", log(&dir));
    assert_eq!(r["found"], true, "{r}");
    let (dp, dr) = pose_error(&r, &root().join("scenes/fig3_table.toml"), "cup");
    assert!(dp < 0.010 && dr < 10.0, "cup off by {dp} m, {dr} deg: {r}");
    let s = c.ask(json!({"cmd":"status"}));
    assert!(s["devices"][0]["kind"].as_str().unwrap().contains("PTU-D46"), "{s}");
}

#[test]
fn an_unplugged_ptu_shows_drops_the_sweep_and_comes_back() {
    let dir = tmpdir("unplug");
    // The PowerCube driver exchanges ~100 telegrams a second while sweeping: unplug a second or
    // so into the first sweep, plug back in 3 s later.
    let (_rig, ptu, sensor) = start_rig(&dir, &["--disconnect-after", "400", "--ptu-replug-after", "3"]);
    let (_d, socket) = start_daemon(&dir, &hardware_config(&ptu, &sensor), &[]);
    unplugged_ptu_comes_back(&dir, &socket);
}

#[test]
fn an_unplugged_flir_ptu_shows_drops_the_sweep_and_comes_back() {
    let dir = tmpdir("unplug-flir");
    // The FLIR driver at 9600 baud polls the unit about 50 times a second: 100 replies is about
    // two seconds into the first sweep (which takes three, the move to its start included).
    let after = FLIR_UNPLUG_AFTER.to_string();
    let (_rig, ptu, sensor) = start_rig_with(
        &dir,
        "flir",
        &[
            "--tilt-sign",
            "-1",
            "--disconnect-after",
            &after,
            "--ptu-replug-after",
            "3",
        ],
    );
    let config = hardware_config_with(&ptu, &sensor, "flir", "sim_rig_flir.toml", 0.80);
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    unplugged_ptu_comes_back(&dir, &socket);
}

const FLIR_UNPLUG_AFTER: u64 = 100;

/// The PTU of a running rig was unplugged mid-sweep and is plugged back in: the fault shows, the
/// sweep is dropped, and a fresh sweep after the replug finds the cup.
fn unplugged_ptu_comes_back(dir: &Path, socket: &Path) {
    unplugged_device_comes_back(dir, socket, 0, "ptu", "PTU");
}

/// Device `k` of `status` (`name`) of a running rig was unplugged mid-sweep and is plugged back
/// in: a dropped sweep, the device's failure and a fault naming it (`fault`) show, and a fresh
/// sweep after the replug finds the cup.
fn unplugged_device_comes_back(dir: &Path, socket: &Path, k: usize, name: &str, fault: &str) {
    let mut c = Client::connect(socket);
    // The fault shows in status: the device down (or back up, with its failure counted) and a
    // dropped sweep (the one under way: its profiles or its moves stopped).
    let t0 = Instant::now();
    let status = loop {
        let s = c.ask(json!({"cmd":"status"}));
        let failures = s["devices"][k]["failures"].as_u64().unwrap();
        if s["sweeps"]["dropped"].as_u64().unwrap() >= 1 && failures >= 1 {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no dropped sweep and {name} failure: {s}\n{}",
            log(dir)
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let device = &status["devices"][k];
    assert_eq!(device["name"], name, "{status}");
    assert!(device["last_error"].is_string(), "{status}");
    assert!(
        status["faults"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["message"].as_str().unwrap().contains(fault)),
        "{status}"
    );
    // Back: a fresh find answers from a sweep made after the replug.
    let r = c.ask(json!({"cmd":"find","object":"cup","max_age_s":0.0,"timeout_s":90}));
    assert_eq!(r["class"], "detection", "{r}\n{}", log(dir));
    assert_eq!(r["found"], true, "{r}");
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["devices"][k]["state"], "ok", "{s}");
    assert!(s["devices"][k]["opens"].as_u64().unwrap() >= 2, "{s}");
}

#[test]
fn on_demand_sweeps_recorded_atomically_and_served_over_tcp() {
    let dir = tmpdir("ondemand");
    let port = free_port();
    let config = format!(
        "{}\n[acquisition]\nmode = \"on_demand\"\n[server]\ntcp = \"127.0.0.1:{port}\"\nframe_id = \"robot_base\"\n[record]\ndir = \"rec\"\nkeep = 2\n",
        sim_config()
    );
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut c = Client::connect(&socket);
    // Nothing is swept until someone needs it.
    std::thread::sleep(Duration::from_millis(800));
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["mode"], "on_demand");
    assert_eq!(s["sweeps"]["completed"], 0, "{s}");
    // find asks for a sweep; so does scan; each is recorded.
    let r = c.ask(json!({"cmd":"find","object":"bowl","timeout_s":30}));
    assert_eq!(r["found"], true, "{r}");
    assert_eq!(r["frame"], "robot_base", "{r}");
    for _ in 0..2 {
        assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":30}))["class"], "sweep");
    }
    let s = c.ask(json!({"cmd":"status"}));
    let done = s["sweeps"]["completed"].as_u64().unwrap();
    assert!((3..=4).contains(&done), "on demand made {done} sweeps: {s}");
    // The newest two recordings, complete (the JSON is renamed last), no temporary files left.
    let rec = dir.join("rec");
    wait_for("the recordings", Duration::from_secs(10), || {
        std::fs::read_dir(&rec).map(|d| d.count() == 4).unwrap_or(false)
    });
    let mut names: Vec<String> = std::fs::read_dir(&rec)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert!(
        names.iter().all(|n| n.starts_with("sweep-") && !n.contains("tmp")),
        "{names:?}"
    );
    let newest = names
        .last()
        .unwrap()
        .trim_end_matches(".pcd")
        .trim_end_matches(".json")
        .to_string();
    let meta: Value =
        serde_json::from_str(&std::fs::read_to_string(rec.join(format!("{newest}.json"))).unwrap()).unwrap();
    let cloud = sqscan::cloud::read_cloud(&rec.join(format!("{newest}.pcd"))).unwrap();
    assert_eq!(cloud.finite_count() as u64, meta["points"].as_u64().unwrap());
    assert_eq!(meta["frame"], "robot_base");
    assert_eq!((cloud.width, cloud.height), (256, 150));
    assert!(cloud.viewpoint.is_some());

    // cloud: the newest sweep's points, in the bytes after the reply's line, as recorded.
    let header = c.ask(json!({"cmd":"cloud","max_age_s":3600,"id":"pts"}));
    assert_eq!(
        (&header["class"], &header["id"]),
        (&json!("cloud"), &json!("pts")),
        "{header}"
    );
    // Compared with the recording of the same sweep (on demand, a fourth sweep may be newer
    // than the newest recording seen above).
    let id = header["sweep"]["id"].as_u64().unwrap();
    wait_for("the cloud's recording", Duration::from_secs(10), || {
        rec.join(format!("sweep-{id:08}.json")).exists()
    });
    let cloud = sqscan::cloud::read_cloud(&rec.join(format!("sweep-{id:08}.pcd"))).unwrap();
    assert_eq!(
        (header["width"].as_u64(), header["height"].as_u64(), &header["frame"]),
        (Some(256), Some(150), &json!("robot_base")),
        "{header}"
    );
    let mut payload = vec![0u8; header["bytes"].as_u64().unwrap() as usize];
    std::io::Read::read_exact(&mut c.r, &mut payload).unwrap();
    let sent = sqscan::cloud::read_pcd(&payload[..]).unwrap();
    assert_eq!(
        (sent.width, sent.height, sent.viewpoint),
        (cloud.width, cloud.height, cloud.viewpoint)
    );
    let same_bits = |a: &[f32; 3], b: &[f32; 3]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
    assert!(sent.points.iter().zip(&cloud.points).all(|(a, b)| same_bits(a, b)));
    let names: Vec<String> = ["x", "y", "z"]
        .iter()
        .map(|s| s.to_string())
        .chain(sent.fields.iter().map(|f| f.name.clone()))
        .collect();
    assert_eq!(json!(names), header["fields"]);
    // The protocol's lines go on after the payload.
    assert_eq!(c.ask(json!({"cmd":"status"}))["class"], "status");

    // The client over TCP.
    let out = Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .env("SQSCAN_MODELS_DIR", root().join("models"))
        .args(["status", "--json", "--socket", &format!("tcp://127.0.0.1:{port}")])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["class"], "status", "{v}");
    assert_eq!(v["mode"], "on_demand", "{v}");
    // sqscan cloud writes the same bytes.
    let file = dir.join("fetched.pcd");
    let out = Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .args(["cloud", "--max-age", "3600", "--out"])
        .arg(&file)
        .args(["--socket", &format!("tcp://127.0.0.1:{port}")])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("256 x 150 points"),
        "{out:?}"
    );
    assert!(
        std::fs::read(&file).unwrap() == payload,
        "sqscan cloud wrote other bytes"
    );
    // The same protocol over TCP.
    let tcp = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    tcp.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut w = tcp.try_clone().unwrap();
    let mut r = BufReader::new(tcp);
    let mut line = String::new();
    r.read_line(&mut line).unwrap();
    assert!(line.contains("\"class\":\"version\""), "{line}");
    w.write_all(b"{\"cmd\":\"models\",\"id\":5}\n").unwrap();
    line.clear();
    r.read_line(&mut line).unwrap();
    let v: Value = serde_json::from_str(&line).unwrap();
    check_reply(&v);
    assert_eq!(
        (v["class"].as_str(), v["id"].as_u64()),
        (Some("models"), Some(5)),
        "{v}"
    );
}

#[test]
fn stalled_clients_do_not_hold_up_acquisition_or_others() {
    let dir = tmpdir("stall");
    let (_d, socket) = start_daemon(&dir, &sim_config(), &[]);
    // One client watches and never reads; one sends half a request and goes quiet; one
    // connects and says nothing.
    let mut watcher = Client::connect(&socket);
    watcher.send(&json!({"cmd":"watch","objects":["bowl","cup"]}));
    let mut half = UnixStream::connect(&socket).unwrap();
    half.write_all(b"{\"cmd\":\"fi").unwrap();
    let _silent = UnixStream::connect(&socket).unwrap();
    let mut c = Client::connect(&socket);
    let first = c.ask(json!({"cmd":"scan","timeout_s":30}))["sweep"]["id"]
        .as_u64()
        .unwrap();
    // Sweeps go on and a fresh find is answered from one made after it was asked.
    let r = c.ask(json!({"cmd":"find","object":"cup","max_age_s":0.0,"timeout_s":30}));
    assert_eq!(r["found"], true, "{r}");
    assert!(r["sweep"]["id"].as_u64().unwrap() > first, "{r}");
    let s = c.ask(json!({"cmd":"status"}));
    assert!(s["clients"]["connected"].as_u64().unwrap() >= 4, "{s}");
    assert!(s["sweeps"]["completed"].as_u64().unwrap() > first, "{s}");
    // The half request, completed later, is still answered.
    half.write_all(b"nd\",\"object\":\"bowl\",\"id\":9}\n").unwrap();
    half.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut r = BufReader::new(half);
    let mut line = String::new();
    r.read_line(&mut line).unwrap(); // version
    line.clear();
    r.read_line(&mut line).unwrap();
    let v: Value = serde_json::from_str(&line).unwrap();
    check_reply(&v);
    assert_eq!(
        (v["class"].as_str(), v["id"].as_u64()),
        (Some("detection"), Some(9)),
        "{v}"
    );
}

/// A backend of the test's own: a 2 x 3 sweep of a flat patch every 20 ms.
struct FlatPatch {
    sweeps: u64,
    /// Panic in this sweep (a backend's bug).
    panic_at: Option<u64>,
}

impl sqscan::daemon::Backend for FlatPatch {
    fn name(&self) -> &'static str {
        "test"
    }

    fn devices(&self) -> Vec<sqscan::daemon::DeviceStatus> {
        let mut d = sqscan::daemon::DeviceStatus::new("patch", "memory".into(), "flat patch".into());
        d.connected = true;
        vec![d]
    }

    async fn sweep(
        &mut self,
        _forward: bool,
        _devices: &sqscan::daemon::Devices,
        _joints: &sqscan::daemon::JointFeed,
    ) -> Result<sqscan::daemon::Swept, sqscan::daemon::SweepFailure> {
        tokio::time::sleep(Duration::from_millis(20)).await;
        self.sweeps += 1;
        assert!(Some(self.sweeps) != self.panic_at, "the test backend's bug");
        let sweep = sqscan::sweep::Sweep::flat_patch(Some(4));
        let started = Instant::now();
        Ok(sqscan::daemon::Swept {
            sweep,
            started,
            last_profile: started,
            recorded: None,
        })
    }

    async fn stop(&mut self) {}
}

/// The daemon serves on a listener and a backend it is handed, and binds nothing itself.
/// A runtime and a daemon serving `backend` on a TCP port of its own (no Unix socket), with the
/// shipped models; `config` as the test sets it.
fn serve_on_tcp(
    mut config: sqscan::daemon::config::Config,
    backend: FlatPatch,
) -> (tokio::runtime::Runtime, sqscan::daemon::Daemon, std::net::SocketAddr) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    config.models_dir = root().join("models");
    let models = sqscan::daemon::load_models(&config.models_dir).unwrap();
    let (daemon, addr) = rt.block_on(async {
        let tcp = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = tcp.local_addr().unwrap();
        let listeners = sqscan::daemon::Listeners {
            unix: None,
            tcp: Some(tcp),
        };
        let daemon = sqscan::daemon::Daemon::serve(config, models, backend, listeners, None).unwrap();
        (daemon, addr)
    });
    (rt, daemon, addr)
}

#[test]
fn a_daemon_runs_on_an_injected_listener_and_backend() {
    let mut config = sqscan::daemon::config::Config::embedded_default();
    let dir = tmpdir("injected");
    // Were the daemon to bind the configured socket, this file would appear.
    config.socket = dir.join("not-bound.sock");
    let backend = FlatPatch {
        sweeps: 0,
        panic_at: None,
    };
    let (rt, daemon, addr) = serve_on_tcp(config, backend);
    assert!(daemon.socket().is_none());

    let s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    let mut ask = |v: Value| -> Value {
        if !v.is_null() {
            w.write_all(format!("{v}\n").as_bytes()).unwrap();
        }
        let mut line = String::new();
        assert!(r.read_line(&mut line).unwrap() > 0, "the daemon closed the connection");
        let v = serde_json::from_str(&line).unwrap();
        check_reply(&v);
        v
    };
    assert_eq!(ask(Value::Null)["class"], "version");
    let sweep = ask(json!({"cmd": "scan", "timeout_s": 10}));
    assert_eq!(sweep["class"], "sweep", "{sweep}");
    assert_eq!(
        (sweep["sweep"]["profiles"].as_u64(), sweep["sweep"]["columns"].as_u64()),
        (Some(2), Some(3))
    );
    assert_eq!(sweep["sweep"]["points"], 5, "{sweep}");
    assert_eq!(sweep["sweep"]["report"]["kept"], 2, "{sweep}");
    let status = ask(json!({"cmd": "status"}));
    assert_eq!(status["backend"], "test", "{status}");
    assert_eq!(status["devices"][0]["name"], "patch", "{status}");
    assert_eq!(status["devices"][0]["state"], "ok", "{status}");
    assert!(!dir.join("not-bound.sock").exists());
    rt.block_on(daemon.stop());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A panic in the acquisition task is not a silent death: `status` reports it (never "ok"),
/// and the daemon's failure resolves, on which `sqscand` stops and exits with an error (and the
/// systemd watchdog stops).
#[test]
fn a_panicking_acquisition_task_is_reported_not_hidden() {
    let backend = FlatPatch {
        sweeps: 0,
        panic_at: Some(3),
    };
    let (rt, daemon, addr) = serve_on_tcp(sqscan::daemon::config::Config::embedded_default(), backend);
    let why = rt
        .block_on(async { tokio::time::timeout(Duration::from_secs(30), daemon.failed()).await })
        .expect("the failure is noticed");
    assert!(
        why.contains("acquisition task panicked: the test backend's bug"),
        "{why}"
    );
    let s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    let mut line = String::new();
    r.read_line(&mut line).unwrap();
    w.write_all(b"{\"cmd\":\"status\"}\n").unwrap();
    line.clear();
    r.read_line(&mut line).unwrap();
    let status: Value = serde_json::from_str(&line).unwrap();
    check_reply(&status);
    assert_eq!(status["failure"], why.as_str(), "{status}");
    rt.block_on(daemon.stop());
}

/// A detection reply without what depends on when and how fast it was made.
fn answer_only(r: &Value) -> Value {
    let mut r = r.clone();
    let o = r.as_object_mut().unwrap();
    for k in ["timing_ms", "latency_ms", "sweep", "id"] {
        o.remove(k);
    }
    r
}

#[test]
fn a_replayed_recording_gives_the_same_answers_to_the_digit() {
    let dir = tmpdir("replay");
    // Record: one sweep on demand, asked for the cup and the bowl.
    let recorder = dir.join("recorder");
    std::fs::create_dir_all(&recorder).unwrap();
    let rec = dir.join("rec");
    let config = format!(
        "{}\n[acquisition]\nmode = \"on_demand\"\n[record]\ndir = \"{}\"\nkeep = 0\n",
        sim_config(),
        rec.display()
    );
    let (daemon, socket) = start_daemon(&recorder, &config, &[]);
    let mut c = Client::connect(&socket);
    // Sweep 1 is recorded and then removed, so that the replayed sweep's own id (1) differs
    // from its recorded one (2), which the detector's seed must come from.
    assert_eq!(c.ask(json!({"cmd":"scan","timeout_s":60}))["class"], "sweep");
    let cup = c.ask(json!({"cmd":"find","object":"cup","max_age_s":0.0,"timeout_s":60}));
    assert_eq!(cup["found"], true, "{cup}");
    let bowl = c.ask(json!({"cmd":"find","object":"bowl","max_age_s":600,"timeout_s":60}));
    assert_eq!(bowl["found"], true, "{bowl}");
    let id = cup["sweep"]["id"].as_u64().unwrap();
    assert_eq!(bowl["sweep"]["id"].as_u64(), Some(id), "{bowl}");
    assert!(cup["sweep"]["recorded"].is_null(), "{cup}");
    wait_for("the recording", Duration::from_secs(10), || {
        rec.join(format!("sweep-{id:08}.json")).exists()
    });
    drop(c);
    drop(daemon);
    assert_eq!(id, 2);
    wait_for("the first recording", Duration::from_secs(10), || {
        rec.join("sweep-00000001.json").exists()
    });
    for ext in ["json", "pcd"] {
        std::fs::remove_file(rec.join(format!("sweep-00000001.{ext}"))).unwrap();
    }

    // Beside the recording, a cloud from elsewhere: an organized PCD with a viewpoint.
    let sim = dir.join("sim");
    let out = Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .env("SQSCAN_MODELS_DIR", root().join("models"))
        .args(["simulate"])
        .arg(root().join("scenes/fig4_tools.toml"))
        .arg("--out")
        .arg(&sim)
        .args(["--seed", "2"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::copy(sim.join("cloud.pcd"), rec.join("tools.pcd")).unwrap();

    // Replay, one sweep a request.
    let player = dir.join("player");
    std::fs::create_dir_all(&player).unwrap();
    let config = format!(
        "[acquisition]\nmode = \"on_demand\"\n[replay]\ndir = \"{}\"\nspeed = 0\n",
        rec.display()
    );
    let (_d, socket) = start_daemon(&player, &config, &[]);
    let mut c = Client::connect(&socket);
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["backend"], "replay", "{s}");
    assert_eq!(s["devices"][0]["name"], "replay", "{s}");
    let cup2 = c.ask(json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(cup2["class"], "detection", "{cup2}\n{}", log(&player));
    assert_eq!(cup2["sweep"]["recorded"]["id"].as_u64(), Some(id), "{cup2}");
    assert_eq!(answer_only(&cup2), answer_only(&cup));
    let bowl2 = c.ask(json!({"cmd":"find","object":"bowl","max_age_s":600,"timeout_s":60}));
    assert_eq!(answer_only(&bowl2), answer_only(&bowl));

    // The next sweep is the other cloud: the mallet's scene.
    let mallet = c.ask(json!({"cmd":"find","object":"mallet","max_age_s":0.0,"timeout_s":60}));
    assert_eq!(mallet["found"], true, "{mallet}");
    assert!(mallet["sweep"]["recorded"]["id"].is_null(), "{mallet}");
    assert!(
        mallet["sweep"]["recorded"]["file"]
            .as_str()
            .unwrap()
            .ends_with("tools.pcd"),
        "{mallet}"
    );
    let (dp, dr) = pose_error(&mallet, &root().join("scenes/fig4_tools.toml"), "mallet");
    assert!(dp < 0.010 && dr < 10.0, "mallet off by {dp} m, {dr} deg: {mallet}");

    // Then the replay is over, and says so at once: not a device fault (a request waited for
    // its whole timeout and got `device`, and `status` said the replay had a fault).
    let t = std::time::Instant::now();
    let r = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert_eq!(
        (&r["class"], &r["code"]),
        (&json!("error"), &json!("replay_finished")),
        "{r}"
    );
    assert!(r["message"].as_str().unwrap().contains("all 2 sweeps served"), "{r}");
    assert!(t.elapsed() < Duration::from_secs(10), "the end took {:?}", t.elapsed());
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["devices"][0]["state"], "finished", "{s}");
    assert!(s["devices"][0]["last_error"].is_null(), "{s}");
    // A request the newest sweep satisfies is still answered.
    let again = c.ask(json!({"cmd":"find","object":"mallet","max_age_s":3600,"timeout_s":60}));
    assert_eq!(again["found"], true, "{again}");
    drop(c);

    // The desk recipe: `--replay DIR --replay-step` on any configuration serves one recorded
    // sweep a `scan`, in order, then says the replay is over.
    let stepper = dir.join("stepper");
    std::fs::create_dir_all(&stepper).unwrap();
    let (_d, socket) = start_daemon_with(&stepper, &sim_config(), &[], |cmd| {
        cmd.arg("--replay").arg(&rec).arg("--replay-step");
    });
    let mut c = Client::connect(&socket);
    let first = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert_eq!(first["sweep"]["recorded"]["id"].as_u64(), Some(id), "{first}");
    // The newest sweep serves a find as long as it is young enough: no step.
    let cup3 = c.ask(json!({"cmd":"find","object":"cup","max_age_s":3600,"timeout_s":60}));
    assert_eq!(answer_only(&cup3), answer_only(&cup), "{cup3}");
    let second = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert!(
        second["sweep"]["recorded"]["file"]
            .as_str()
            .unwrap()
            .ends_with("tools.pcd"),
        "{second}"
    );
    let end = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert_eq!(end["code"], "replay_finished", "{end}");
}

// A GigE Vision rig (the mock camera on aravis's emulator, the PowerCube on a pty) runs only
// inside a private network namespace with only loopback.
use crate::common::root;
#[cfg(feature = "gige")]
use sqscan_drivers::mock::gige::in_private_network;

/// The daemon's configuration for the mock rig's PowerCube on `ptu` and its camera on
/// 127.0.0.1; `sensor` adds to `[hardware.sensor]`.
#[cfg(feature = "gige")]
fn gige_config(ptu: &Path, sensor: &str) -> String {
    format!(
        r#"
[hardware]
calibration = "{}"
ptu = {{ path = "{}", protocol = "powercube" }}
[hardware.sensor]
kind = "gige"
address = "127.0.0.1"
{sensor}
[sweep]
tilt_from_rad = 0.49
tilt_to_rad = 0.84
speed_rad_s = 0.12
timeout_s = 5.0
"#,
        root().join("calibration/sim_rig.toml").display(),
        ptu.display(),
    )
}

#[cfg(feature = "gige")]
#[test]
fn a_gige_vision_rig_finds_the_cup() {
    if !in_private_network("daemon::a_gige_vision_rig_finds_the_cup") {
        return;
    }
    let dir = tmpdir("gige");
    // The camera's clock a day ahead of the host's and 100 ppm fast: the sweep is assembled on
    // the host's clock all the same.
    let (_rig, ptu, _sensor) = start_rig(
        &dir,
        &[
            "--sensor",
            "gige",
            "--rows-per-frame",
            "10",
            "--camera-clock-offset",
            "86400",
            "--camera-clock-drift",
            "100",
        ],
    );
    // The camera powers up in its 2D mode: the configuration asks for profiles by feature name.
    let config = gige_config(
        &ptu,
        "rows_per_frame = 10\nfeatures = [\n  { name = \"DeviceScanType\", value = \"Linescan3D\" },\n  { name = \"PixelFormat\", value = \"Coord3D_C16\" },\n]",
    );
    wait_for("the camera", Duration::from_secs(10), || {
        std::fs::read_to_string(dir.join("rig.log")).is_ok()
    });
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    let mut c = Client::connect(&socket);
    let r = c.ask(json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(r["class"], "detection", "{r}\n{}", log(&dir));
    assert_eq!(r["found"], true, "{r}\n{}", log(&dir));
    let (dp, dr) = pose_error(&r, &root().join("scenes/fig3_table.toml"), "cup");
    assert!(dp < 0.010 && dr < 10.0, "cup off by {dp} m, {dr} deg: {r}");
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["devices"][1]["path"], "gige://127.0.0.1", "{s}");
    assert_eq!(s["devices"][1]["state"], "ok", "{s}");
    let scan = c.ask(json!({"cmd":"scan","timeout_s":60}));
    assert!(scan["sweep"]["profiles"].as_u64().unwrap() >= 100, "{scan}");
    assert_eq!(
        scan["sweep"]["report"]["profile_times"], "block_and_line_rate",
        "{scan}"
    );
}

#[cfg(feature = "gige")]
#[test]
fn an_unplugged_gige_camera_drops_the_sweep_and_comes_back() {
    if !in_private_network("daemon::an_unplugged_gige_camera_drops_the_sweep_and_comes_back") {
        return;
    }
    let dir = tmpdir("gige-unplug");
    // Sweeps take about 3.2 s from the first at about 0.3 s: 5 s is in the middle of the second.
    let (_rig, ptu, _sensor) = start_rig(
        &dir,
        &[
            "--sensor",
            "gige",
            "--camera-unplug-after",
            "5",
            "--camera-replug-after",
            "3",
        ],
    );
    let config = gige_config(
        &ptu,
        "features = [{ name = \"DeviceScanType\", value = \"Linescan3D\" }]",
    );
    let (_d, socket) = start_daemon(&dir, &config, &[]);
    unplugged_device_comes_back(&dir, &socket, 1, "sensor", "sensor");
}

/// A camera that answers but is not a line-profile camera (aravis's stock emulator: no
/// `AcquisitionLineRate`) was retried forever while `find` said no sweep had completed: the
/// daemon now stops at start naming the feature, leaving no socket.
#[cfg(feature = "gige")]
#[test]
fn a_gige_camera_without_a_needed_feature_stops_the_start_naming_it() {
    if !in_private_network("daemon::a_gige_camera_without_a_needed_feature_stops_the_start_naming_it") {
        return;
    }
    let dir = tmpdir("gige-stock");
    let (_rig, ptu, _sensor) = start_rig(&dir, &[]);
    let _camera = sqscan_drivers::mock::gige::StockFakeCamera::start("127.0.0.1").unwrap();
    // A range format it has: the first feature it lacks is then the line rate.
    let config = gige_config(&ptu, "features = [{ name = \"PixelFormat\", value = \"Mono16\" }]");
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let socket = dir.join("sqscand.sock");
    let out = Command::new(env!("CARGO_BIN_EXE_sqscand"))
        .arg("--config")
        .arg(dir.join("sqscand.toml"))
        .arg("--socket")
        .arg(&socket)
        .env("SQSCAN_MODELS_DIR", root().join("models"))
        .env_remove("NOTIFY_SOCKET")
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "started with a 2D camera: {err}");
    assert!(
        err.contains("sensor gige://127.0.0.1") && err.contains("camera feature AcquisitionLineRate"),
        "{err}"
    );
    assert!(!socket.exists(), "a socket was left behind");
}

/// A camera that does not answer yet (a robot may power it later) does not stop the start: the
/// daemon serves, says the sensor is down and why, and keeps trying.
#[cfg(feature = "gige")]
#[test]
fn an_unreachable_gige_camera_is_retried() {
    if !in_private_network("daemon::an_unreachable_gige_camera_is_retried") {
        return;
    }
    let dir = tmpdir("gige-absent");
    let (_rig, ptu, _sensor) = start_rig(&dir, &[]);
    let (_d, socket) = start_daemon(&dir, &gige_config(&ptu, ""), &[]);
    let mut c = Client::connect(&socket);
    wait_for("two failed opens of the camera", Duration::from_secs(30), || {
        let s = c.ask(json!({"cmd":"status"}));
        s["devices"][1]["failures"].as_u64().is_some_and(|n| n >= 2)
    });
    let s = c.ask(json!({"cmd":"status"}));
    assert_eq!(s["devices"][1]["state"], "fault", "{s}");
    assert!(
        s["devices"][1]["last_error"].as_str().unwrap().contains("127.0.0.1"),
        "{s}"
    );
}

/// A models directory with the shipped models and one broken file, which the daemon logs as an
/// error and skips.
fn models_with_a_broken_one(dir: &Path) -> PathBuf {
    let models = dir.join("models");
    std::fs::create_dir_all(&models).unwrap();
    for e in std::fs::read_dir(root().join("models")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            std::fs::copy(&p, models.join(p.file_name().unwrap())).unwrap();
        }
    }
    std::fs::write(models.join("broken.toml"), "name = \"broken\"\n[[part]]\na = [\n").unwrap();
    models
}

/// A model file named with a terminal's escape sequence and a line break was logged raw: the
/// terminal cleared and a forged log line.
#[test]
fn a_file_name_with_escape_sequences_and_a_line_break_is_logged_escaped() {
    let dir = tmpdir("log-escaped");
    let models = models_with_a_broken_one(&dir);
    std::fs::rename(models.join("broken.toml"), models.join("b\u{1b}[2J\nforged line.toml")).unwrap();
    let config = format!("{}\n[server]\nmodels_dir = \"{}\"\n", sim_config(), models.display());
    let (d, socket) = start_daemon(&dir, &config, &[]);
    Client::connect(&socket).ask(json!({"cmd":"status"}));
    drop(d);
    let text = log(&dir);
    let line = text
        .lines()
        .find(|l| l.contains("skipping a model"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains("[2J\\nforged line.toml"), "{line}");
    assert!(!text.contains('\u{1b}'), "an escape byte in the log: {text:?}");
    assert!(!text.lines().any(|l| l.starts_with("forged")), "a forged line: {text}");
}

#[test]
fn logs_carry_no_colour_codes_and_journal_lines_carry_their_priority() {
    use std::os::unix::fs::MetadataExt;
    // Stderr a file: plain lines, no escape byte.
    let dir = tmpdir("log-plain");
    let config = format!(
        "{}\n[server]\nmodels_dir = \"{}\"\n",
        sim_config(),
        models_with_a_broken_one(&dir).display()
    );
    let (d, socket) = start_daemon(&dir, &config, &[]);
    Client::connect(&socket).ask(json!({"cmd":"status"}));
    drop(d);
    let text = log(&dir);
    assert!(text.contains("skipping a model"), "{text}");
    assert!(!text.contains('\u{1b}'), "escape codes in a file: {text:?}");

    // Stderr the journal's stream: each line starts with its syslog priority.
    let dir = tmpdir("log-journal");
    let config = format!(
        "{}\n[server]\nmodels_dir = \"{}\"\n",
        sim_config(),
        models_with_a_broken_one(&dir).display()
    );
    // The file start_daemon makes stderr keeps this inode (it is truncated, not replaced).
    let m = std::fs::File::create(dir.join("sqscand.log"))
        .unwrap()
        .metadata()
        .unwrap();
    let stream = format!("{}:{}", m.dev(), m.ino());
    let (d, socket) = start_daemon(&dir, &config, &[("JOURNAL_STREAM", stream.as_str())]);
    Client::connect(&socket).ask(json!({"cmd":"status"}));
    drop(d);
    let text = log(&dir);
    assert!(!text.contains('\u{1b}'), "escape codes in the journal: {text:?}");
    let line = |what: &str| {
        text.lines()
            .find(|l| l.contains(what))
            .unwrap_or_else(|| panic!("no line with {what:?}: {text}"))
            .to_string()
    };
    assert!(line("skipping a model").starts_with("<3>"), "{text}");
    assert!(line("scanning with").starts_with("<6>"), "{text}");
    // journald stamps the lines itself.
    assert!(!line("scanning with").contains("Z "), "{text}");
}
