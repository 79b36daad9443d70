//! The live view (the `foxglove` feature): the daemon serves the Foxglove WebSocket protocol
//! (subprotocols `foxglove.sdk.v1.1`, `foxglove.sdk.v1` and its former name
//! `foxglove.websocket.v1`, through Foxglove's SDK, patched in `vendor/foxglove` for the last) on
//! a loopback address, and publishes, as
//! ROS 2 messages in CDR (the same encoding as the MCAP recordings and the ROS 2 node,
//! `crate::ros`):
//! - `/sqscan/points`, `sensor_msgs/msg/PointCloud2`: every completed sweep;
//! - `/sqscan/range`, `sensor_msgs/msg/Image`: its range image (`32FC1`, m);
//! - `/sqscan/joint_states`, `sensor_msgs/msg/JointState`: the PTU's pan and tilt at each of the
//!   sweep's profiles;
//! - `/tf`, `tf2_msgs/msg/TFMessage`: the same joints as transforms at each profile, and
//!   `/tf_static` with the rig's mount: with each sweep, and to each client as it subscribes (a
//!   viewer that joins between sweeps has the mount at once, as from ROS's latched topic);
//! - `/sqscan/detections`, `vision_msgs/msg/Detection3DArray`: every detection as it is made
//!   (asked by a client or watched), one object a message, an empty array for "not here";
//! - `/sqscan/markers`, `visualization_msgs/msg/MarkerArray`: the latest detection's fitted
//!   parts as points on their surfaces, a colour a part, and the support plane.
//!
//! Foxglove decodes `ros2msg` schemas with CDR itself; nothing of ROS needs to be installed.

use std::net::SocketAddr;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{ChannelBuilder, PartialMetadata, RawChannel, Schema, WebSocketServer};

use super::backend::Mount;
use super::state::{Shared, SweepEntry};
use super::topics;
use crate::ros::{Time, schema};

struct Channels {
    points: Arc<RawChannel>,
    range: Arc<RawChannel>,
    joints: Arc<RawChannel>,
    tf: Arc<RawChannel>,
    tf_static: Arc<RawChannel>,
    detections: Arc<RawChannel>,
    markers: Arc<RawChannel>,
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
        shared.fail(msg);
    }
}

/// Sends the rig's mount on `/tf_static` to a client as it subscribes: the mount changes never,
/// and a viewer must not wait for the next sweep to place the sensor.
struct Latched {
    shared: Arc<Shared>,
    tf_static: Arc<RawChannel>,
}

impl ServerListener for Latched {
    fn on_subscribe(&self, _client: Client, channel: ChannelView) {
        if channel.id() != self.tf_static.id() {
            return;
        }
        let Some(m) = self.shared.mount() else {
            return;
        };
        let frame = self.shared.config().frame_id.clone();
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let stamp = Time::from_unix_s(now);
        // The other subscribers get it once more: the same transforms, which they keep as they are.
        self.tf_static
            .log_with_meta(&topics::tf_static(&frame, m, stamp), at(stamp));
    }
}

async fn serve(shared: &Arc<Shared>, listen: SocketAddr) -> Result<()> {
    let mount = shared.mount().copied();
    let ctx = foxglove::Context::new();
    let channels = Channels {
        points: channel(&ctx, topics::POINTS, schema::POINT_CLOUD2, schema::point_cloud2())?,
        range: channel(&ctx, topics::RANGE, schema::IMAGE, schema::image())?,
        joints: channel(&ctx, topics::JOINTS, schema::JOINT_STATE, schema::joint_state())?,
        tf: channel(&ctx, "/tf", schema::TF_MESSAGE, schema::tf_message())?,
        tf_static: channel(&ctx, "/tf_static", schema::TF_MESSAGE, schema::tf_message())?,
        detections: channel(
            &ctx,
            topics::DETECTIONS,
            schema::DETECTION3D_ARRAY,
            schema::detection3d_array(),
        )?,
        markers: channel(&ctx, topics::MARKERS, schema::MARKER_ARRAY, schema::marker_array())?,
    };
    // A viewer that does not read loses its oldest messages once its queue holds this many
    // bytes: the crate's own bound counts messages (1024 of them: a thousand sweeps when only
    // the points are subscribed to).
    let backlog = shared.config().foxglove_backlog_bytes;
    let server = WebSocketServer::new()
        .name("sqscand")
        .message_backlog_bytes(backlog)
        .listener(Arc::new(Latched {
            shared: shared.clone(),
            tf_static: channels.tf_static.clone(),
        }))
        .bind(listen.ip().to_string(), listen.port())
        .context(&ctx)
        .start()
        .await
        .context("cannot start the server")?;
    tracing::info!("Foxglove view on ws://{listen}");
    let channels = Arc::new(channels);
    let mut follow = topics::Follow::new(shared, "the Foxglove view");
    while let Some(event) = follow.next().await {
        match event {
            topics::Event::Sweep(entry) => {
                let c = channels.clone();
                let frame = shared.config().frame_id.clone();
                // Encoding a 600 000-point cloud takes a few milliseconds: off the runtime.
                let _ = tokio::task::spawn_blocking(move || publish_sweep(&c, &entry, &frame, mount.as_ref())).await;
            }
            topics::Event::Detection((entry, model, d)) => {
                let frame = shared.config().frame_id.clone();
                let c = channels.clone();
                // Sampling the parts' surfaces for the markers: off the runtime too.
                let _ = tokio::task::spawn_blocking(move || {
                    let one = [(model, d)];
                    let (stamp, data) = topics::detections(&entry, &one, &frame);
                    c.detections.log_with_meta(&data, at(stamp));
                    if c.markers.has_sinks() {
                        let (stamp, data) = topics::markers(&entry, &one, &frame);
                        c.markers.log_with_meta(&data, at(stamp));
                    }
                })
                .await;
            }
            // The view draws each sweep's joint states with the sweep.
            topics::Event::Joints(_) => {}
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

fn publish_sweep(c: &Channels, entry: &SweepEntry, frame: &str, mount: Option<&Mount>) {
    if let Some(m) = mount {
        let stamp = Time::from_unix_s(topics::last_profile_unix_s(entry));
        c.tf_static
            .log_with_meta(&topics::tf_static(frame, m, stamp), at(stamp));
    }
    if c.joints.has_sinks() {
        for (stamp, data) in topics::joint_states(entry) {
            c.joints.log_with_meta(&data, at(stamp));
        }
    }
    if c.tf.has_sinks() {
        for (stamp, data) in topics::tf_joints(entry) {
            c.tf.log_with_meta(&data, at(stamp));
        }
    }
    if c.range.has_sinks() {
        let (stamp, data) = topics::range_image(entry);
        c.range.log_with_meta(&data, at(stamp));
    }
    if c.points.has_sinks() {
        let (stamp, data) = topics::cloud(entry, frame);
        c.points.log_with_meta(&data, at(stamp));
    }
}
