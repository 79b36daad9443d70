//! The live view (the `foxglove` feature): the daemon serves the Foxglove WebSocket protocol
//! (subprotocol `foxglove.sdk.v1`, through Foxglove's SDK) on a loopback address, and publishes, as
//! ROS 2 messages in CDR (the same encoding as the MCAP recordings, `crate::ros`):
//! - `/sqscan/points`, `sensor_msgs/msg/PointCloud2`: every completed sweep;
//! - `/sqscan/joint_states`, `sensor_msgs/msg/JointState`: the PTU's pan and tilt at each of the
//!   sweep's profiles;
//! - `/sqscan/detections`, `vision_msgs/msg/Detection3DArray`: every detection as it is made
//!   (asked by a client or watched), one object a message, an empty array for "not here".
//!
//! Foxglove decodes `ros2msg` schemas with CDR itself; nothing of ROS needs to be installed.

use std::net::SocketAddr;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use foxglove::{ChannelBuilder, PartialMetadata, RawChannel, Schema, WebSocketServer};

use super::state::{Shared, SweepEntry};
use super::topics;
use crate::ros::{Time, schema};

struct Channels {
    points: Arc<RawChannel>,
    joints: Arc<RawChannel>,
    detections: Arc<RawChannel>,
}

fn channel(ctx: &Arc<foxglove::Context>, topic: &str, name: &str, text: String) -> Result<Arc<RawChannel>> {
    ChannelBuilder::new(topic)
        .context(ctx)
        .message_encoding("cdr")
        .schema(Schema::new(name, "ros2msg", text.into_bytes()))
        .build_raw()
        .with_context(|| format!("the live view's channel {topic}"))
}

/// Serves the view on `listen` until the daemon stops. A view that cannot start stops the daemon
/// (the configuration asked for it).
pub async fn run(shared: Arc<Shared>, listen: SocketAddr) {
    if let Err(e) = serve(&shared, listen).await {
        let msg = format!("the Foxglove view on {listen}: {e:#}");
        tracing::error!("{msg}");
        shared.failure.send_replace(Some(msg));
    }
}

async fn serve(shared: &Arc<Shared>, listen: SocketAddr) -> Result<()> {
    let ctx = foxglove::Context::new();
    let server = WebSocketServer::new()
        .name("sqscand")
        .bind(listen.ip().to_string(), listen.port())
        .context(&ctx)
        .start()
        .await
        .context("cannot start the server")?;
    tracing::info!("Foxglove view on ws://{listen}");
    let channels = Channels {
        points: channel(&ctx, topics::POINTS, schema::POINT_CLOUD2, schema::point_cloud2())?,
        joints: channel(&ctx, topics::JOINTS, schema::JOINT_STATE, schema::joint_state())?,
        detections: channel(
            &ctx,
            topics::DETECTIONS,
            schema::DETECTION3D_ARRAY,
            schema::detection3d_array(),
        )?,
    };
    let mut follow = topics::Follow::new(shared, "the Foxglove view");
    while let Some(event) = follow.next().await {
        match event {
            topics::Event::Sweep(entry) => {
                let (c, f) = (channels.points.clone(), channels.joints.clone());
                let frame = shared.config().frame_id.clone();
                // Encoding a 600 000-point cloud takes a few milliseconds: off the runtime.
                let _ = tokio::task::spawn_blocking(move || publish_sweep(&c, &f, &entry, &frame)).await;
            }
            topics::Event::Detection((entry, model, d)) => {
                let frame = shared.config().frame_id.clone();
                let (stamp, data) = topics::detections(&entry, &[(model, d)], &frame);
                channels.detections.log_with_meta(&data, at(stamp));
            }
        }
    }
    let _ = server.stop();
    Ok(())
}

fn at(stamp: Time) -> PartialMetadata {
    PartialMetadata {
        log_time: Some(stamp.nanos()),
    }
}

fn publish_sweep(points: &RawChannel, joints: &RawChannel, entry: &SweepEntry, frame: &str) {
    if joints.has_sinks() {
        for (stamp, data) in topics::joint_states(entry) {
            joints.log_with_meta(&data, at(stamp));
        }
    }
    if points.has_sinks() {
        let (stamp, data) = topics::cloud(entry, frame);
        points.log_with_meta(&data, at(stamp));
    }
}
