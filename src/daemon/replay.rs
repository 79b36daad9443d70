//! The replay backend: recorded sweeps served again, so that a detection a robot made in the
//! field can be made again on a desk, to the digit.
//!
//! A replay directory holds the daemon's own recordings (`sweep-NNNNNNNN.json` beside its
//! `.pcd`, see [`super::record`]) and any other organized PCD with a viewpoint (one row a
//! profile, as `sqscan simulate` and other tools write them) or, with the `mcap` feature, MCAP
//! file with one (the daemon's own MCAP recordings, see [`crate::cloud::io`]). Recordings are served in the order
//! of their sweep ids, then the other clouds in the order of their names. A recording keeps its
//! sweep id for the detector's seed, so the same cloud, models and `detect.seed` give the same
//! answers as when it was recorded.
//!
//! Pace: a recording follows the one before it after the time that passed between them when
//! they were recorded, divided by `speed` (`speed = 0`: as soon as the daemon asks). Clouds
//! without a recording's time follow at once.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use serde::Deserialize;

use crate::cloud::{PointCloud, read_cloud};
use crate::sweep::{Sweep, SweepReport};

use super::backend::{Backend, DeviceStatus, Devices, JointFeed, Recorded, SweepFailure, Swept};

/// The one device the replay shows in `status`.
const DEVICE: &str = "replay";

/// One sweep to serve.
#[derive(Debug, Clone, PartialEq)]
struct Item {
    cloud: PathBuf,
    /// The recording's sweep id and Unix time of completion; `None` for a cloud that is not one
    /// of the daemon's recordings.
    id: Option<u64>,
    time: Option<f64>,
    report: Option<SweepReport>,
}

/// What the replay reads of a recording's JSON (the rest is for people).
#[derive(Deserialize)]
struct RecordingMeta {
    id: u64,
    time: f64,
    cloud: String,
    /// The same sweep as MCAP beside it (`[record] mcap`): not served a second time.
    mcap: Option<String>,
    report: Option<SweepReport>,
}

/// Recorded sweeps, served in order.
pub struct ReplayBackend {
    dir: PathBuf,
    items: Vec<Item>,
    speed: f64,
    looping: bool,
    next: usize,
    /// When the previous sweep was handed over, and its recorded time.
    previous: Option<(Instant, Option<f64>)>,
}

impl ReplayBackend {
    /// Indexes `dir`. Errors name the file that is wrong; a directory with nothing to serve is an
    /// error. The clouds themselves are read when served (see [`Self::check_all`]).
    pub fn new(dir: &Path, speed: f64, looping: bool) -> Result<ReplayBackend> {
        if !(speed.is_finite() && (0.0..=1000.0).contains(&speed)) {
            bail!("replay speed {speed}: give 0 (as fast as asked) or a factor up to 1000");
        }
        let items = index(dir)?;
        Ok(ReplayBackend {
            dir: dir.to_owned(),
            items,
            speed,
            looping,
            next: 0,
            previous: None,
        })
    }

    /// Sweeps in the directory.
    pub fn sweeps(&self) -> usize {
        self.items.len()
    }

    /// Reads every cloud once (`sqscand --check`): the first that cannot be served is an error.
    pub fn check_all(&self) -> Result<()> {
        for item in &self.items {
            load(item).map_err(|m| anyhow::anyhow!(m))?;
        }
        Ok(())
    }

    /// How long to wait before handing over `item`, given the previous one.
    fn wait_before(&self, item: &Item) -> Option<Instant> {
        let (at, prev_time) = self.previous?;
        if self.speed == 0.0 {
            return None;
        }
        let gap = item.time? - prev_time?;
        // A clock stepped back between two recordings: no wait. A wait no clock holds (a tiny
        // speed): the longest one that does, a hundred days.
        if !(gap.is_finite() && gap > 0.0) {
            return None;
        }
        Some(at + Duration::from_secs_f64((gap / self.speed).min(1e7)))
    }
}

/// The directory's sweeps in serving order.
fn index(dir: &Path) -> Result<Vec<Item>> {
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("cannot list the replay directory {}", dir.display()))?;
    let mut names: Vec<String> = Vec::new();
    for e in entries {
        let e = e.with_context(|| format!("cannot list the replay directory {}", dir.display()))?;
        // Names that are not UTF-8 are no recording of ours and no cloud we could name.
        if let Ok(n) = e.file_name().into_string() {
            // Dot files are a recording in progress (`atomic::write_atomic`) or not ours.
            if !n.starts_with('.') {
                names.push(n);
            }
        }
    }
    names.sort();
    let mut recorded: Vec<Item> = Vec::new();
    let mut claimed: Vec<String> = Vec::new();
    for n in names.iter().filter(|n| n.starts_with("sweep-") && n.ends_with(".json")) {
        let path = dir.join(n);
        // Bounded and without blocking: a FIFO named like a recording would hold the daemon's
        // start for a writer that never comes.
        let text = crate::spec::read_text(&path).with_context(|| format!("cannot read {}", path.display()))?;
        let meta: RecordingMeta =
            serde_json::from_str(&text).with_context(|| format!("{}: not a sweep recording", path.display()))?;
        // The cloud lies beside its JSON: a name, not a path that could lead anywhere else.
        if meta.cloud.is_empty() || meta.cloud.contains('/') || meta.cloud.starts_with('.') {
            bail!(
                "{}: cloud {:?}: give the file name of the PCD beside it",
                path.display(),
                meta.cloud
            );
        }
        if !meta.time.is_finite() {
            bail!("{}: time {}: not a time", path.display(), meta.time);
        }
        let cloud = dir.join(&meta.cloud);
        if !cloud.is_file() {
            bail!("{}: its cloud {} is missing", path.display(), cloud.display());
        }
        claimed.push(meta.cloud.clone());
        claimed.extend(meta.mcap.clone());
        recorded.push(Item {
            cloud,
            id: Some(meta.id),
            time: Some(meta.time),
            report: meta.report,
        });
    }
    // sqscand's MCAP recordings without their JSON keep their sweep ids and times (in their
    // `sqscan.sweep` metadata); one that cannot be read is served with the other clouds, and
    // its error is the dropped sweep's.
    #[cfg(feature = "mcap")]
    {
        let unclaimed: Vec<&String> = names
            .iter()
            .filter(|n| n.to_ascii_lowercase().ends_with(".mcap") && !claimed.contains(n))
            .collect();
        for n in unclaimed {
            let cloud = dir.join(n);
            if let Ok(Some((id, time))) = crate::cloud::io::mcap_recorded_sweep(&cloud) {
                claimed.push(n.clone());
                recorded.push(Item {
                    cloud,
                    id: Some(id),
                    time: Some(time),
                    report: None,
                });
            }
        }
    }
    recorded.sort_by_key(|i| i.id);
    // MCAP files only where this build reads them.
    let served = |n: &str| {
        let n = n.to_ascii_lowercase();
        n.ends_with(".pcd") || (cfg!(feature = "mcap") && n.ends_with(".mcap"))
    };
    let others = names
        .iter()
        .filter(|n| served(n) && !claimed.contains(n))
        .map(|n| Item {
            cloud: dir.join(n),
            id: None,
            time: None,
            report: None,
        });
    recorded.extend(others);
    if recorded.is_empty() {
        bail!(
            "the replay directory {} holds no sweep: give a directory of recordings (sweep-*.json and .pcd) or of organized PCD files",
            dir.display()
        );
    }
    Ok(recorded)
}

/// A recorded cloud as a sweep. The recording keeps the organized cloud and the assembler's
/// report; the per-profile stamps and joint angles are not recorded, and are NaN.
fn load(item: &Item) -> Result<Sweep, String> {
    let path = &item.cloud;
    let cloud: PointCloud = read_cloud(path).map_err(|e| format!("replay: {e}"))?;
    if cloud.height < 2 {
        return Err(format!(
            "replay: {}: an unorganized cloud (HEIGHT {}): a sweep has one row a profile",
            path.display(),
            cloud.height
        ));
    }
    let Some(view) = cloud.viewpoint_position() else {
        return Err(format!(
            "replay: {}: no VIEWPOINT: the detector needs to know where the sensor was",
            path.display()
        ));
    };
    let (profiles, columns) = (cloud.height, cloud.width);
    // Range from the viewpoint (the sensor at mid-sweep), the nearest the recording holds to
    // each profile's own range.
    let range_m: Vec<f32> = cloud
        .points
        .iter()
        .map(|p| {
            if p.iter().all(|c| c.is_finite()) {
                let d = [0, 1, 2].map(|k| f64::from(p[k]) - view[k]);
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let points = cloud.finite_count();
    let report = item.report.clone().unwrap_or(SweepReport {
        received: profiles,
        kept: profiles,
        points,
        ..SweepReport::default()
    });
    Ok(Sweep {
        profiles,
        columns,
        start: None,
        stamp_s: vec![f64::NAN; profiles],
        seq: (0..profiles as u32).collect(),
        pan_rad: vec![f64::NAN; profiles],
        tilt_rad: vec![f64::NAN; profiles],
        range_m,
        cloud,
        report,
    })
}

impl Backend for ReplayBackend {
    fn name(&self) -> &'static str {
        "replay"
    }

    fn devices(&self) -> Vec<DeviceStatus> {
        let mut d = DeviceStatus::new(
            DEVICE,
            self.dir.display().to_string(),
            format!("recorded sweeps: {}", self.items.len()),
        );
        d.connected = true;
        d.opens = 1;
        vec![d]
    }

    async fn sweep(&mut self, _forward: bool, devices: &Devices, joints: &JointFeed) -> Result<Swept, SweepFailure> {
        if self.next == self.items.len() {
            if !self.looping {
                let n = self.items.len();
                devices.note_finished(DEVICE, &format!("the replay is over: all {n} sweeps served"));
                // Nothing more to serve: wait for the daemon to stop. The sweeps served stay
                // available to clients.
                std::future::pending::<()>().await;
            }
            self.next = 0;
            self.previous = None;
        }
        let item = self.items[self.next].clone();
        self.next += 1;
        if let Some(at) = self.wait_before(&item) {
            tokio::time::sleep_until(at.into()).await;
        }
        let started = Instant::now();
        let loaded = {
            let item = item.clone();
            let name = item.cloud.display().to_string();
            tokio::task::spawn_blocking(move || load(&item))
                .await
                .map_err(|e| format!("replay: reading {name} failed: {e}"))
                .and_then(|r| r)
        };
        self.previous = Some((Instant::now(), item.time));
        match loaded {
            Ok(sweep) => {
                let last_profile = Instant::now();
                joints.send_profiles(&sweep, last_profile);
                Ok(Swept {
                    sweep,
                    started,
                    last_profile,
                    recorded: Some(Recorded {
                        id: item.id,
                        file: item.cloud,
                    }),
                })
            }
            Err(message) => {
                devices.note_error(DEVICE, &message);
                Err(SweepFailure { message })
            }
        }
    }

    async fn stop(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::{PcdData, write_pcd};

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("sqscan-replay-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A FIFO named like a sweep recording: reading it waited for a writer that never came,
    /// and the daemon never started. It is refused at once, by name.
    #[test]
    fn a_fifo_named_like_a_recording_is_refused_without_blocking() {
        let d = tmp("fifo");
        let out = std::process::Command::new("mkfifo")
            .arg(d.join("sweep-000001.json"))
            .output()
            .unwrap();
        assert!(out.status.success(), "mkfifo: {}", String::from_utf8_lossy(&out.stderr));
        let (tx, rx) = std::sync::mpsc::channel();
        let dir = d.clone();
        std::thread::spawn(move || {
            let _ = tx.send(
                ReplayBackend::new(&dir, 1.0, false)
                    .map(|_| ())
                    .map_err(|e| format!("{e:#}")),
            );
        });
        let e = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("still blocked after 10 s")
            .unwrap_err();
        assert!(
            e.contains("sweep-000001.json") && e.contains("not a regular file"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    fn organized(rows: usize, cols: usize) -> PointCloud {
        let mut c = PointCloud::from_points(
            (0..rows * cols)
                .map(|i| {
                    if i % 7 == 0 {
                        [f32::NAN; 3]
                    } else {
                        [i as f32 * 1e-3, 0.1, 0.7]
                    }
                })
                .collect(),
        );
        c.width = cols;
        c.height = rows;
        c.viewpoint = Some([0.0, 0.0, 1.5, 1.0, 0.0, 0.0, 0.0]);
        c
    }

    fn write(path: &Path, c: &PointCloud) {
        let mut f = std::fs::File::create(path).unwrap();
        write_pcd(&mut f, c, PcdData::BinaryCompressed).unwrap();
    }

    fn meta(dir: &Path, id: u64, time: f64) {
        let v = serde_json::json!({"id": id, "time": time, "cloud": format!("sweep-{id:08}.pcd"), "report": null});
        std::fs::write(dir.join(format!("sweep-{id:08}.json")), v.to_string()).unwrap();
        write(&dir.join(format!("sweep-{id:08}.pcd")), &organized(3, 4));
    }

    #[test]
    fn recordings_by_id_then_other_clouds_by_name() {
        let d = tmp("order");
        meta(&d, 12, 100.0);
        meta(&d, 9, 98.0);
        write(&d.join("b.pcd"), &organized(2, 2));
        write(&d.join("a.pcd"), &organized(2, 2));
        std::fs::write(d.join(".sweep-00000013.json.tmp7"), "half").unwrap();
        std::fs::write(d.join("notes.txt"), "x").unwrap();
        let r = ReplayBackend::new(&d, 1.0, false).unwrap();
        let order: Vec<String> = r
            .items
            .iter()
            .map(|i| i.cloud.file_name().unwrap().to_str().unwrap().to_string())
            .collect();
        assert_eq!(order, ["sweep-00000009.pcd", "sweep-00000012.pcd", "a.pcd", "b.pcd"]);
        assert_eq!(r.items[0].id, Some(9));
        r.check_all().unwrap();
        let s = load(&r.items[1]).unwrap();
        assert_eq!((s.profiles, s.columns), (3, 4));
        assert_eq!(
            s.range_m.iter().filter(|r| r.is_finite()).count(),
            s.cloud.finite_count()
        );
        // 0.8 m below the viewpoint, at x = 1 mm: the range of point 1.
        assert!((s.range_m[1] - (0.8f32.powi(2) + 0.1f32.powi(2) + 1e-6).sqrt()).abs() < 1e-5);
    }

    #[test]
    fn the_recorded_pace_divided_by_the_speed() {
        let d = tmp("pace");
        meta(&d, 1, 100.0);
        meta(&d, 2, 102.0);
        let mut r = ReplayBackend::new(&d, 4.0, false).unwrap();
        let now = Instant::now();
        assert_eq!(r.wait_before(&r.items[0].clone()), None);
        r.previous = Some((now, Some(100.0)));
        let at = r.wait_before(&r.items[1].clone()).unwrap();
        assert!((at.duration_since(now).as_secs_f64() - 0.5).abs() < 1e-9);
        r.speed = 0.0;
        assert_eq!(r.wait_before(&r.items[1].clone()), None);
        // A clock stepped back: no wait, no panic.
        r.speed = 1.0;
        r.previous = Some((now, Some(200.0)));
        assert_eq!(r.wait_before(&r.items[1].clone()), None);
    }

    #[test]
    fn broken_replay_directories_are_named() {
        let d = tmp("empty");
        let e = ReplayBackend::new(&d, 1.0, false).err().unwrap().to_string();
        assert!(e.contains("holds no sweep"), "{e}");
        let e = ReplayBackend::new(&d.join("nope"), 1.0, false)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("cannot list"), "{e}");
        assert!(ReplayBackend::new(&d, f64::NAN, false).is_err());
        assert!(ReplayBackend::new(&d, -1.0, false).is_err());

        let d = tmp("corrupt");
        std::fs::write(d.join("sweep-00000001.json"), "{\"id\": 1,").unwrap();
        let e = format!("{:#}", ReplayBackend::new(&d, 1.0, false).err().unwrap());
        assert!(
            e.contains("sweep-00000001.json") && e.contains("not a sweep recording"),
            "{e}"
        );

        let d = tmp("escape");
        std::fs::write(
            d.join("sweep-00000001.json"),
            r#"{"id":1,"time":5.0,"cloud":"../../etc/passwd"}"#,
        )
        .unwrap();
        let e = ReplayBackend::new(&d, 1.0, false).err().unwrap().to_string();
        assert!(e.contains("give the file name"), "{e}");

        let d = tmp("missing");
        std::fs::write(d.join("sweep-00000001.json"), r#"{"id":1,"time":5.0,"cloud":"x.pcd"}"#).unwrap();
        let e = ReplayBackend::new(&d, 1.0, false).err().unwrap().to_string();
        assert!(e.contains("is missing"), "{e}");
    }

    #[test]
    fn unorganized_clouds_and_clouds_without_a_viewpoint_are_refused_by_name() {
        let d = tmp("shape");
        write(&d.join("flat.pcd"), &organized(1, 12));
        // No VIEWPOINT line at all (a writer of ours always gives one).
        std::fs::write(
            d.join("blind.pcd"),
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 2\nPOINTS 4\nDATA ascii\n\
             0 0 1\n0 1 1\n1 0 1\n1 1 1\n",
        )
        .unwrap();
        std::fs::write(d.join("junk.pcd"), "VERSION 0.7\nFIELDS x y z\n").unwrap();
        let r = ReplayBackend::new(&d, 0.0, false).unwrap();
        let errors: Vec<String> = r.items.iter().map(|i| load(i).err().unwrap()).collect();
        assert!(
            errors[0].contains("blind.pcd") && errors[0].contains("VIEWPOINT"),
            "{errors:?}"
        );
        assert!(
            errors[1].contains("flat.pcd") && errors[1].contains("unorganized"),
            "{errors:?}"
        );
        assert!(errors[2].contains("junk.pcd"), "{errors:?}");
        assert!(r.check_all().is_err());
    }

    #[tokio::test]
    async fn serves_each_once_then_says_it_is_over_or_starts_again() {
        let d = tmp("serve");
        meta(&d, 1, 10.0);
        write(&d.join("broken.pcd"), &organized(1, 3));
        meta(&d, 2, 11.0);
        let devices = Devices::default();
        let joints = JointFeed::default();
        let mut r = ReplayBackend::new(&d, 0.0, false).unwrap();
        devices.set(r.devices());
        let a = r.sweep(true, &devices, &joints).await.unwrap();
        assert_eq!(a.recorded.as_ref().unwrap().id, Some(1));
        assert_eq!(
            r.sweep(true, &devices, &joints).await.unwrap().recorded.unwrap().id,
            Some(2)
        );
        let e = r.sweep(true, &devices, &joints).await.err().unwrap();
        assert!(e.message.contains("broken.pcd"), "{}", e.message);
        let over = tokio::time::timeout(Duration::from_millis(200), r.sweep(true, &devices, &joints)).await;
        assert!(over.is_err(), "a finished replay must wait, not fail in a loop");
        let s = &devices.snapshot()[0];
        // Finished, not failed: the broken file's error stays the last one.
        assert!(
            !s.connected && s.finished.as_deref().unwrap().contains("all 3 sweeps served"),
            "{s:?}"
        );
        assert!(s.last_error.as_deref().unwrap().contains("broken.pcd"), "{s:?}");
        assert_eq!(s.json().state, crate::daemon::reply::DeviceState::Finished);
        assert!(devices.finished().is_some() && devices.trouble().is_empty());

        let mut r = ReplayBackend::new(&d, 0.0, true).unwrap();
        for _ in 0..3 {
            let _ = r.sweep(true, &devices, &joints).await;
        }
        assert_eq!(
            r.sweep(true, &devices, &joints).await.unwrap().recorded.unwrap().id,
            Some(1)
        );
    }
}
