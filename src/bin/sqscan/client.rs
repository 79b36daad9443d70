//! The daemon's client: `sqscan find | status | watch | scan | models`. One connection, one
//! request (with an id), the reply printed for people or, with `--json`, as the daemon sent it.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Args;
use nalgebra::{Quaternion, UnitQuaternion};
use serde_json::{Value, json};
use sqscan::daemon::config::client_socket_candidates;
use sqscan::daemon::reply::{PROTO_MAJOR, PROTO_MINOR};

/// Where and how to talk to the daemon.
#[derive(Args, Clone)]
pub struct ClientArgs {
    /// The daemon's socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp)
    /// [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else
    /// /run/sqscan/sqscand.sock: the first that exists]
    #[arg(long, value_name = "PATH")]
    socket: Option<PathBuf>,
    /// Print the daemon's JSON replies as they are, one a line
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct FindArgs {
    /// Object (model) name, e.g. cup
    object: String,
    /// Accept a sweep up to this old (s); else wait for the next one
    #[arg(long, value_name = "S", default_value_t = 2.0)]
    max_age: f64,
    /// Give up after this long (s)
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    timeout: f64,
    /// Every instance, not only the best
    #[arg(long)]
    all: bool,
    /// Up to N grasps of the daemon's gripper for each found instance, best first
    #[arg(long, value_name = "N", default_value_t = 0)]
    grasps: usize,
    #[command(flatten)]
    client: ClientArgs,
}

#[derive(Args)]
pub struct WatchArgs {
    /// Objects to report on every sweep
    #[arg(required = true)]
    objects: Vec<String>,
    /// Stop after this many detection messages (default: until interrupted)
    #[arg(long, value_name = "N")]
    count: Option<u64>,
    /// Up to N grasps of the daemon's gripper for each found instance, best first
    #[arg(long, value_name = "N", default_value_t = 0)]
    grasps: usize,
    #[command(flatten)]
    client: ClientArgs,
}

#[derive(Args)]
pub struct ScanArgs {
    /// Give up after this long (s)
    #[arg(long, value_name = "S", default_value_t = 30.0)]
    timeout: f64,
    #[command(flatten)]
    client: ClientArgs,
}

#[derive(Args)]
pub struct CloudArgs {
    /// Write the sweep's points here (a binary PCD file, organized, with the sensor's viewpoint)
    #[arg(long, value_name = "FILE.pcd")]
    out: PathBuf,
    /// Accept a sweep up to this old (s); else wait for the next one
    #[arg(long, value_name = "S", default_value_t = 2.0)]
    max_age: f64,
    /// Give up after this long (s)
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    timeout: f64,
    #[command(flatten)]
    client: ClientArgs,
}

#[derive(Args)]
pub struct PlainArgs {
    #[command(flatten)]
    client: ClientArgs,
}

/// A connection to the daemon: its Unix socket, or TCP.
enum Stream {
    Unix(UnixStream),
    Tcp(TcpStream),
}

impl Stream {
    fn try_clone(&self) -> std::io::Result<Stream> {
        Ok(match self {
            Stream::Unix(s) => Stream::Unix(s.try_clone()?),
            Stream::Tcp(s) => Stream::Tcp(s.try_clone()?),
        })
    }

    fn set_read_timeout(&self, t: Option<Duration>) -> std::io::Result<()> {
        match self {
            Stream::Unix(s) => s.set_read_timeout(t),
            Stream::Tcp(s) => s.set_read_timeout(t),
        }
    }
}

impl Read for Stream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self {
            Stream::Unix(s) => s.read(buf),
            Stream::Tcp(s) => s.read(buf),
        }
    }
}

impl Write for Stream {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Stream::Unix(s) => s.write(buf),
            Stream::Tcp(s) => s.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Stream::Unix(s) => s.flush(),
            Stream::Tcp(s) => s.flush(),
        }
    }
}

struct Connection {
    reader: BufReader<Stream>,
    writer: Stream,
    /// Where, as the user gave it.
    path: String,
}

impl Connection {
    fn open(a: &ClientArgs) -> Result<Connection> {
        let path = match &a.socket {
            Some(p) => p.clone(),
            None => {
                let c = client_socket_candidates();
                c.iter().find(|p| p.exists()).cloned().unwrap_or_else(|| c[0].clone())
            }
        };
        let shown = path.display().to_string();
        let stream = match shown.strip_prefix("tcp://") {
            Some(addr) => TcpStream::connect(addr).map(Stream::Tcp),
            None => UnixStream::connect(&path).map(Stream::Unix),
        }
        .with_context(|| {
            format!("cannot connect to the daemon at {shown} (is sqscand running? --socket names another)")
        })?;
        let writer = stream.try_clone().context("cloning the socket")?;
        let mut c = Connection {
            reader: BufReader::new(stream),
            writer,
            path: shown,
        };
        let hello = c.read()?;
        // A daemon with every slot busy answers an error instead of the greeting.
        fail_on_error(&hello).with_context(|| format!("the daemon at {} refused the connection", c.path))?;
        if hello["class"] != "version" {
            bail!("{} did not greet like sqscand: {hello}", c.path);
        }
        if hello["proto_major"] != PROTO_MAJOR {
            bail!(
                "{} speaks protocol {}.{}, this client {PROTO_MAJOR}.{PROTO_MINOR}: use the sqscan of the daemon's release ({})",
                c.path,
                hello["proto_major"],
                hello["proto_minor"],
                hello["release"]
            );
        }
        Ok(c)
    }

    fn send(&mut self, v: &Value) -> Result<()> {
        let mut s = v.to_string();
        s.push('\n');
        self.writer.write_all(s.as_bytes()).context("sending the request")
    }

    fn read(&mut self) -> Result<Value> {
        let mut line = String::new();
        let n = self.reader.read_line(&mut line).context("reading from the daemon")?;
        if n == 0 {
            bail!("the daemon at {} closed the connection", self.path);
        }
        serde_json::from_str(&line).with_context(|| format!("the daemon sent something that is not JSON: {line:?}"))
    }

    /// The `n` bytes of payload that follow a reply's line.
    fn read_payload(&mut self, n: usize) -> Result<Vec<u8>> {
        let mut buf = vec![0u8; n];
        self.reader
            .read_exact(&mut buf)
            .with_context(|| format!("reading the {n} bytes of payload from {}", self.path))?;
        Ok(buf)
    }

    /// Sends a request and returns its reply (by id), passing over anything else.
    fn request(&mut self, mut v: Value, wait: Duration) -> Result<Value> {
        v["id"] = json!(1);
        self.send(&v)?;
        self.reader
            .get_ref()
            .set_read_timeout(Some(wait))
            .context("setting a timeout")?;
        loop {
            let r = self.read()?;
            if r["id"] == json!(1) || (r["class"] == "error" && r.get("id").is_none()) {
                return Ok(r);
            }
        }
    }
}

fn fail_on_error(r: &Value) -> Result<()> {
    if r["class"] == "error" {
        bail!(
            "{} ({})",
            r["message"].as_str().unwrap_or("the daemon refused the request"),
            r["code"].as_str().unwrap_or("no code")
        );
    }
    Ok(())
}

fn fmt_pose(p: &Value) -> String {
    let pos: Vec<f64> = p["position"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let q: Vec<f64> = p["orientation"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    if pos.len() != 3 || q.len() != 4 {
        return "no pose".into();
    }
    let uq = UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]));
    let (r, pi, y) = uq.euler_angles();
    format!(
        "at x {:.3} y {:.3} z {:.3} m, roll {:.1} pitch {:.1} yaw {:.1} deg",
        pos[0],
        pos[1],
        pos[2],
        r.to_degrees(),
        pi.to_degrees(),
        y.to_degrees()
    )
}

/// One line for a detection reply.
/// A detection's grasps, a line each: kind, part, opening, pose.
fn grasp_lines(d: &Value, indent: &str) -> String {
    let mut s = String::new();
    for g in d["grasps"].as_array().into_iter().flatten() {
        s += &format!(
            "\n{indent}grasp {} {}: opening {:.1} mm, {}",
            g["kind"].as_str().unwrap_or("?"),
            g["part"].as_str().unwrap_or("?"),
            g["opening_m"].as_f64().unwrap_or(f64::NAN) * 1e3,
            fmt_pose(&g["pose"])
        );
    }
    s
}

fn detection_line(r: &Value) -> String {
    let object = r["object"].as_str().unwrap_or("?");
    let sweep = format!(
        "sweep {} ({:.1} s old, {} points)",
        r["sweep"]["id"],
        r["sweep"]["age_s"].as_f64().unwrap_or(f64::NAN),
        r["sweep"]["points"]
    );
    if let Some(ds) = r["detections"].as_array() {
        if ds.is_empty() || !ds.iter().any(|d| d["found"] == true) {
            return format!("{object}: not found in {sweep}");
        }
        let mut s = format!(
            "{object}: {} found in {sweep}",
            ds.iter().filter(|d| d["found"] == true).count()
        );
        for d in ds.iter().filter(|d| d["found"] == true) {
            s += &format!(
                "\n  {} (confidence {:.2})",
                fmt_pose(&d["pose"]),
                d["confidence"].as_f64().unwrap_or(0.0)
            );
            s += &grasp_lines(d, "    ");
        }
        return s;
    }
    if r["found"] == true {
        format!(
            "{object}: found {} (confidence {:.2}) in {sweep}{}",
            fmt_pose(&r["pose"]),
            r["confidence"].as_f64().unwrap_or(0.0),
            grasp_lines(r, "  ")
        )
    } else {
        format!("{object}: not found in {sweep}")
    }
}

fn print(json_out: bool, r: &Value, human: impl FnOnce(&Value) -> String) {
    if json_out {
        println!("{r}");
    } else {
        println!("{}", human(r));
    }
}

pub fn find(a: FindArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let req = json!({"cmd": "find", "object": a.object, "max_age_s": a.max_age, "timeout_s": a.timeout, "all": a.all, "grasps": a.grasps});
    let r = c.request(req, Duration::from_secs_f64(a.timeout + 30.0))?;
    fail_on_error(&r)?;
    print(a.client.json, &r, detection_line);
    Ok(())
}

pub fn cloud(a: CloudArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let r = c.request(
        json!({"cmd": "cloud", "max_age_s": a.max_age, "timeout_s": a.timeout}),
        Duration::from_secs_f64(a.timeout + 30.0),
    )?;
    fail_on_error(&r)?;
    let n = r["bytes"]
        .as_u64()
        .with_context(|| format!("the daemon's cloud reply names no payload length: {r}"))?;
    let payload = c.read_payload(n as usize)?;
    std::fs::write(&a.out, &payload).with_context(|| format!("cannot write {}", a.out.display()))?;
    print(a.client.json, &r, |r| {
        format!(
            "sweep {}: {} x {} points ({}) in {} -> {}",
            r["sweep"]["id"],
            r["width"],
            r["height"],
            r["fields"]
                .as_array()
                .map(|f| f.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(" "))
                .unwrap_or_default(),
            r["frame"].as_str().unwrap_or("?"),
            a.out.display()
        )
    });
    Ok(())
}

pub fn scan(a: ScanArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let r = c.request(
        json!({"cmd": "scan", "timeout_s": a.timeout}),
        Duration::from_secs_f64(a.timeout + 30.0),
    )?;
    fail_on_error(&r)?;
    print(a.client.json, &r, |r| {
        let s = &r["sweep"];
        format!(
            "sweep {}: {} points from {} profiles x {} columns in {:.2} s",
            s["id"],
            s["points"],
            s["profiles"],
            s["columns"],
            s["duration_s"].as_f64().unwrap_or(f64::NAN)
        )
    });
    Ok(())
}

pub fn watch(a: WatchArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let r = c.request(
        json!({"cmd": "watch", "objects": a.objects, "grasps": a.grasps}),
        Duration::from_secs(30),
    )?;
    fail_on_error(&r)?;
    if a.client.json {
        println!("{r}");
    }
    // Sweeps come every few seconds; a daemon silent for long is reported, not waited on forever.
    c.reader
        .get_ref()
        .set_read_timeout(Some(Duration::from_secs(120)))
        .context("setting a timeout")?;
    let mut seen = 0u64;
    while a.count.is_none_or(|n| seen < n) {
        let r = c.read()?;
        fail_on_error(&r)?;
        if r["class"] == "detection" {
            seen += 1;
            print(a.client.json, &r, detection_line);
        }
    }
    Ok(())
}

pub fn status(a: PlainArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let r = c.request(json!({"cmd": "status"}), Duration::from_secs(10))?;
    fail_on_error(&r)?;
    print(a.client.json, &r, |r| {
        let mut s = format!(
            "sqscand {} up {:.0} s, {} backend, {} acquisition",
            r["release"].as_str().unwrap_or("?"),
            r["uptime_s"].as_f64().unwrap_or(0.0),
            r["backend"].as_str().unwrap_or("?"),
            r["mode"].as_str().unwrap_or("?")
        );
        for d in r["devices"].as_array().into_iter().flatten() {
            s += &format!(
                "\n{:>9}: {} {} ({}), opened {} times, {} failures",
                d["name"].as_str().unwrap_or("?"),
                d["state"].as_str().unwrap_or("?"),
                d["path"].as_str().unwrap_or("?"),
                d["kind"].as_str().unwrap_or("?"),
                d["opens"],
                d["failures"]
            );
            if let Some(e) = d["last_error"].as_str() {
                s += &format!("; last error: {e}");
            }
        }
        let sw = &r["sweeps"];
        s += &format!("\n   sweeps: {} completed, {} dropped", sw["completed"], sw["dropped"]);
        if let Some(rate) = sw["per_minute"].as_f64() {
            s += &format!(", {rate:.1} a minute");
        }
        match r["last_sweep"].as_object() {
            Some(l) => {
                s += &format!(
                    "\n     last: sweep {} {:.1} s ago, {} points",
                    l["id"],
                    l["age_s"].as_f64().unwrap_or(f64::NAN),
                    l["points"]
                )
            }
            None => s += "\n     last: none yet",
        }
        let d = &r["detections"];
        s += &format!("\n  detects: {} made", d["count"]);
        if let Some(ms) = d["median_run_ms"].as_f64() {
            s += &format!(", median {ms:.1} ms");
        }
        let cl = &r["clients"];
        s += &format!(
            "\n  clients: {} connected, {} requests",
            cl["connected"], cl["requests"]
        );
        let cf = &r["config"];
        s += &format!(
            "\n   config: {}, models from {}, {} reloads",
            cf["file"].as_str().unwrap_or("built-in defaults"),
            cf["models_dir"].as_str().unwrap_or("?"),
            cf["reloads"]
        );
        if let Some(e) = cf["reload_error"].as_str() {
            s += &format!("; the last reload was refused: {e}");
        }
        for f in r["faults"].as_array().into_iter().flatten().rev().take(3) {
            s += &format!("\n    fault: {}", f["message"].as_str().unwrap_or("?"));
        }
        s
    });
    Ok(())
}

pub fn models(a: PlainArgs) -> Result<()> {
    let mut c = Connection::open(&a.client)?;
    let r = c.request(json!({"cmd": "models"}), Duration::from_secs(10))?;
    fail_on_error(&r)?;
    print(a.client.json, &r, |r| {
        r["models"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|m| {
                let parts: Vec<String> = m["parts"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|p| p["name"].as_str().unwrap_or("?").to_string())
                    .collect();
                format!("{:<18} {}", m["name"].as_str().unwrap_or("?"), parts.join(" + "))
            })
            .collect::<Vec<_>>()
            .join("\n")
    });
    Ok(())
}
