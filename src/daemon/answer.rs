//! The replies to a client's requests, beside `watch` and `unwatch` (which change its
//! connection, see `connection.rs`).

use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::Semaphore;

use crate::detect::output::{add_grasps, report_json};
use crate::grasp::Gripper;
use crate::model::Model;

use super::cloud::{Payload, cloud};
use super::protocol::{Command, Request};
use super::reply::{DetectionReply, ErrorCode, ModelJson, ModelPart, Models, Reply, SweepReply};
use super::state::{Shared, SweepEntry, round3};
use super::waiting::wait_for_sweep;

/// The `detection` reply: the detector's JSON (with `grasps` grasps of `gripper` for each
/// found instance of `model`), the sweep it was made on and how old that is.
pub fn detection_reply(
    entry: &SweepEntry,
    det: &super::state::Detected,
    all: bool,
    frame: &str,
    grasps: Option<(&Model, &Gripper, usize)>,
) -> Reply {
    let mut report = report_json(&det.report, all);
    if let Some((model, gripper, n)) = grasps.filter(|g| g.2 > 0) {
        let cloud = &entry.sweep.cloud;
        add_grasps(
            &mut report,
            &det.report,
            model,
            &cloud.points,
            cloud.viewpoint_position(),
            gripper,
            n,
        );
    }
    Reply::Detection(Box::new(DetectionReply {
        id: None,
        report,
        frame: frame.to_string(),
        sweep: entry.reference(),
        latency_ms: round3(det.latency.as_secs_f64() * 1e3),
    }))
}

/// Answers one request (not watch/unwatch, which change the connection): the reply, and the
/// payload that follows its line (`cloud`'s points).
pub(super) async fn handle(
    shared: &Arc<Shared>,
    req: &Request,
    gate: Arc<Semaphore>,
    all_read: &(dyn Fn() -> bool + Send + Sync),
) -> (Reply, Option<Payload>) {
    match &req.command {
        Command::Cloud { max_age_s, timeout_s } => cloud(shared, *max_age_s, *timeout_s, gate, all_read).await,
        _ => (answer(shared, req).await, None),
    }
}

/// The reply to a request without a payload.
pub(super) async fn answer(shared: &Arc<Shared>, req: &Request) -> Reply {
    match &req.command {
        Command::Status => Reply::Status(Box::new(shared.status())),
        Command::Models => models_reply(shared),
        Command::Find {
            object,
            max_age_s,
            timeout_s,
            all,
            grasps,
        } => {
            let model = match shared.model(object) {
                Ok(m) => m,
                Err(e) => return Reply::error(None, ErrorCode::UnknownObject, e),
            };
            let asked = Instant::now();
            let deadline = asked + Duration::from_secs_f64(*timeout_s);
            let max_age = Duration::from_secs_f64(*max_age_s);
            let fresh = |e: &SweepEntry| e.age() <= max_age || e.completed >= asked;
            let entry = match wait_for_sweep(shared, deadline, fresh).await {
                Ok(e) => e,
                Err((code, msg)) => return Reply::error(None, code, format!("find {object}: {msg}")),
            };
            let det = entry.detection(shared, model.clone(), *all).await;
            let config = shared.config();
            detection_reply(
                &entry,
                &det,
                *all,
                &config.frame_id,
                Some((&model, &config.gripper, *grasps)),
            )
        }
        Command::Scan { timeout_s } => {
            let asked = Instant::now();
            let deadline = asked + Duration::from_secs_f64(*timeout_s);
            // A sweep begun after the request: it shows the scene as it is now.
            match wait_for_sweep(shared, deadline, |e| e.started >= asked).await {
                Ok(e) => Reply::Sweep(Box::new(SweepReply {
                    id: None,
                    sweep: e.summary(),
                })),
                Err((code, msg)) => Reply::error(None, code, format!("scan: {msg}")),
            }
        }
        Command::Watch { .. } | Command::Unwatch | Command::Cloud { .. } => {
            Reply::error(None, ErrorCode::Internal, "handled elsewhere")
        }
    }
}

fn models_reply(shared: &Shared) -> Reply {
    let models = shared
        .models()
        .values()
        .map(|m| ModelJson {
            name: m.name.clone(),
            parts: m
                .parts
                .iter()
                .map(|p| ModelPart {
                    name: p.name.clone(),
                    size_m: p.shape.a,
                    shape: [p.shape.e1, p.shape.e2],
                    taper: [p.shape.kx, p.shape.ky],
                    open: p.open,
                })
                .collect(),
        })
        .collect();
    Reply::Models(Models { id: None, models })
}
