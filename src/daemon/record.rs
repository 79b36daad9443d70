//! Recording sweeps: each as `sweep-NNNNNNNN.pcd` (organized, binary_compressed, viewpoint set)
//! beside `sweep-NNNNNNNN.json` (id, time, the assembler's report), and with `[record] mcap` (the
//! `mcap` feature) `sweep-NNNNNNNN.mcap` too: the same sweep and the watched objects' detections
//! as ROS 2 messages ([`super::record_mcap`]). Every file is written to a temporary name, synced,
//! then renamed into place, so a reader (or a crash) never sees half a file; the JSON is renamed
//! last, so a JSON on disk means the rest of its recording is complete.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;

use crate::atomic::write_atomic;
use crate::cloud::{PcdData, write_pcd};

use super::state::SweepEntry;

/// The recording's file stem for a sweep id.
pub fn stem(id: u64) -> String {
    format!("sweep-{id:08}")
}

/// What goes into a recording besides the PCD and the JSON.
#[derive(Default)]
pub struct Extras {
    /// The MCAP file, with these detections (the `mcap` feature; without it, nothing).
    pub mcap: Option<
        Vec<(
            std::sync::Arc<crate::model::Model>,
            std::sync::Arc<super::state::Detected>,
        )>,
    >,
    /// The rig's fixed transforms, for the MCAP file's `/tf_static`.
    pub mount: Option<super::backend::Mount>,
}

/// Records one sweep whole or not at all: when any of its files cannot be written (a full disk),
/// those already written are removed, so no PCD or MCAP is left without its JSON.
pub fn write_sweep(dir: &Path, entry: &SweepEntry, frame: &str, extras: Extras) -> Result<()> {
    fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let written = write_files(dir, entry, frame, extras);
    if written.is_err() {
        let stem = stem(entry.id);
        for ext in ["json", "mcap", "pcd"] {
            let _ = fs::remove_file(dir.join(format!("{stem}.{ext}")));
        }
    }
    written
}

fn write_files(dir: &Path, entry: &SweepEntry, frame: &str, extras: Extras) -> Result<()> {
    let stem = stem(entry.id);
    write_atomic(&dir.join(format!("{stem}.pcd")), |w| {
        write_pcd(w, &entry.sweep.cloud, PcdData::BinaryCompressed)?;
        Ok(())
    })?;
    #[cfg_attr(not(feature = "mcap"), allow(unused_mut))]
    let mut meta = json!({
        "id": entry.id,
        "time": entry.time_s(),
        "frame": frame,
        "profiles": entry.sweep.profiles,
        "columns": entry.sweep.columns,
        "points": entry.points,
        "viewpoint": entry.sweep.cloud.viewpoint,
        "cloud": format!("{stem}.pcd"),
        "report": entry.sweep.report,
        "release": env!("CARGO_PKG_VERSION"),
    });
    #[cfg(feature = "mcap")]
    if let Some(detections) = &extras.mcap {
        let name = format!("{stem}.mcap");
        let stats =
            super::record_mcap::write(&dir.join(&name), entry, detections, extras.mount.as_ref(), frame, &meta)?;
        meta["mcap"] = json!(name);
        meta["bag"] = serde_json::to_value(stats)?;
    }
    #[cfg(not(feature = "mcap"))]
    let _ = extras;
    write_atomic(&dir.join(format!("{stem}.json")), |w| {
        serde_json::to_writer_pretty(&mut *w, &meta)?;
        w.write_all(b"\n")?;
        Ok(())
    })
}

/// Makes the directory's MCAP files a rosbag2 bag again after a sweep was recorded or pruned
/// (its `metadata.yaml`, [`super::bag`]), where MCAP files are recorded (`mcap`) or a bag is
/// already there (recorded before, its files being pruned); without the `mcap` feature, nothing.
pub fn index(dir: &Path, mcap: bool) -> Result<()> {
    #[cfg(feature = "mcap")]
    if mcap || dir.join(super::bag::METADATA).exists() {
        return super::bag::write_metadata(dir).context("the bag's metadata.yaml");
    }
    let _ = (dir, mcap);
    Ok(())
}

/// Removes all but the newest `keep` recordings (by id in the name), PCD and JSON together;
/// `keep` 0 keeps all.
pub fn prune(dir: &Path, keep: usize) -> Result<()> {
    if keep == 0 {
        return Ok(());
    }
    let mut ids: Vec<u64> = fs::read_dir(dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            name.strip_prefix("sweep-")?.strip_suffix(".json")?.parse().ok()
        })
        .collect();
    ids.sort_unstable();
    let excess = ids.len().saturating_sub(keep);
    for id in &ids[..excess] {
        // The JSON first: a PCD without its JSON is an unfinished recording, never the reverse.
        for ext in ["json", "pcd", "mcap"] {
            let p: PathBuf = dir.join(format!("{}.{ext}", stem(*id)));
            if let Err(e) = fs::remove_file(&p)
                && e.kind() != std::io::ErrorKind::NotFound
            {
                return Err(e).with_context(|| format!("cannot remove {}", p.display()));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::read_cloud;
    use crate::daemon::backend::Swept;
    use crate::sweep::Sweep;
    use std::time::Instant;

    #[test]
    fn records_atomically_and_prunes() {
        let dir = std::env::temp_dir().join(format!("sqscan-record-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        for id in 1..=4 {
            let mut sweep = Sweep::flat_patch(Some(2));
            sweep.cloud.viewpoint = Some([0.0, 0.0, 1.35, 1.0, 0.0, 0.0, 0.0]);
            let e = SweepEntry::new(
                id,
                Swept {
                    sweep,
                    started: Instant::now(),
                    last_profile: Instant::now(),
                    recorded: None,
                },
            );
            write_sweep(&dir, &e, "base_link", Extras::default()).unwrap();
            prune(&dir, 2).unwrap();
        }
        let mut names: Vec<String> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(
            names,
            [
                "sweep-00000003.json",
                "sweep-00000003.pcd",
                "sweep-00000004.json",
                "sweep-00000004.pcd"
            ]
        );
        let back = read_cloud(&dir.join("sweep-00000004.pcd")).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        assert!(back.points[2][0].is_nan());
        assert_eq!(back.viewpoint.unwrap()[2], 1.35);
        let meta: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(dir.join("sweep-00000004.json")).unwrap()).unwrap();
        assert_eq!(meta["points"], 5);
        assert_eq!(meta["report"]["kept"], 2);
        fs::remove_dir_all(&dir).unwrap();
    }
}
