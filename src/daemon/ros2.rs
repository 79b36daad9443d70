//! ROS 2 over DDS (the `ros2` feature): sqscand is a ROS 2 node, through `ros2-client` on
//! RustDDS, that ROS 2's own nodes discover and subscribe to, with no ROS installed here. It
//! publishes, in the configured namespace, QoS and frame (`[ros2]`, `docs/ROS2.md`):
//! - the points topic (default `/sqscan/points`, `sensor_msgs/msg/PointCloud2`): every
//!   completed sweep, organized, stamped with its last profile's time;
//! - the joint states (`/sqscan/joint_states`, `sensor_msgs/msg/JointState`): the PTU's pan and
//!   tilt as each sweep goes (every position sample a rig's PTU gives, each profile's angles
//!   from the simulator), for `robot_state_publisher`;
//! - the detections (`/sqscan/detections`, `vision_msgs/msg/Detection3DArray`): every
//!   detection as it is made, one object a message, an empty array for "not here";
//! - the markers (`/sqscan/markers`, `visualization_msgs/msg/MarkerArray`): each detection's
//!   fitted parts and the support plane, drawn (for rviz);
//! - the range image (`/sqscan/range`, `sensor_msgs/msg/Image`, `32FC1`): every sweep's;
//! - `/tf_static` (`tf2_msgs/msg/TFMessage`, transient local): the PTU's mount in the base frame
//!   and the sensor's on the tilt link, from the rig's calibration;
//! - `/tf` (`tf2_msgs/msg/TFMessage`, with `publish_tf`, the default): the pan and tilt joints as
//!   transforms with each joint state, so that the sensor's frame reaches the base frame with no
//!   `robot_state_publisher`.
//!
//! The messages are encoded once, by `crate::ros` (as the MCAP recordings and the live view
//! carry them), and handed to RustDDS's serializer as they are ([`Encoded`]).
//!
//! Publishing runs on a thread of its own: a reliable writer may wait for a slow subscriber's
//! acknowledgements, and that must not hold up the daemon's runtime.

use std::ops::Range;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::SystemTime;

use anyhow::{Context as _, Result, anyhow};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    qos::{Durability, History, Reliability, WhenFull},
};
use serde::ser::{Serialize, SerializeTuple, Serializer};
use tokio::sync::mpsc;

use super::config::Ros2Config;
use super::state::Shared;
use super::topics::{self, Event};
use crate::ros::{self, Time};

/// How long a reliable writer waits for room in its window before the message is dropped: a
/// subscriber that does not acknowledge must not stall the sweeps.
const WAIT_WHEN_FULL: std::time::Duration = std::time::Duration::from_millis(200);

/// The pause before each joint state. They come at a PTU's sample rate (20-50 ms apart) while
/// a sweep goes, but all at once from a replay or a simulator that does not keep the rig's pace;
/// published back to back, a sweep's 150 joint states reached a Cyclone DDS subscriber with a
/// run of 30 to 100 of them missing in about one sweep in ten, and the reliable writer never
/// repaired the run; paced, none went missing in 30 sweeps. 150 of them take 30 ms.
const JOINT_STATE_PACE: std::time::Duration = std::time::Duration::from_micros(200);

use topics::JOINT_STATES_PER_SWEEP;

/// A message in CDR as `crate::ros` encodes it (with its 4-byte encapsulation header), given to
/// RustDDS's CDR serializer, which writes the body as it is: byte by byte, but for `blob`, the
/// contents of one `uint8[]` (a cloud's `data`), which goes through the serializer's bulk byte
/// sequence (its length, then the bytes). The serializer aligns from the body's start, as
/// `crate::ros` does, so the bytes come out the same.
pub struct Encoded {
    cdr: Vec<u8>,
    blob: Option<Range<usize>>,
}

impl Encoded {
    pub fn new(cdr: Vec<u8>) -> Encoded {
        Encoded { cdr, blob: None }
    }

    /// A `PointCloud2`: its `data` is the `uint8[]` before the last byte (`is_dense`).
    pub fn point_cloud2(cdr: Vec<u8>) -> Encoded {
        let blob = crate::cloud::point_cloud2_data(&cdr);
        Encoded { cdr, blob }
    }

    /// An `Image`: its `data` is the `uint8[]` that ends the message.
    pub fn image(cdr: Vec<u8>) -> Encoded {
        let blob = ros::image_data(&cdr);
        Encoded { cdr, blob }
    }
}

/// A failed write hands the message back in its error: shown by its size, not its bytes.
impl std::fmt::Debug for Encoded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a message of {} bytes", self.cdr.len())
    }
}

struct Bytes<'a>(&'a [u8]);

impl Serialize for Bytes<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(self.0)
    }
}

impl Serialize for Encoded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let body = &self.cdr[4.min(self.cdr.len())..];
        let mut t = s.serialize_tuple(body.len())?;
        match &self.blob {
            // The blob's length prefix (4 bytes) is written by the bulk sequence itself.
            Some(r) if r.start >= 8 && r.end <= self.cdr.len() => {
                for b in &self.cdr[4..r.start - 4] {
                    t.serialize_element(b)?;
                }
                t.serialize_element(&Bytes(&self.cdr[r.clone()]))?;
                for b in &self.cdr[r.end..] {
                    t.serialize_element(b)?;
                }
            }
            _ => {
                for b in body {
                    t.serialize_element(b)?;
                }
            }
        }
        t.end()
    }
}

/// Sweeps and detections waiting for the publishing thread; past this the newest is dropped
/// with a warning (a sweep holds its cloud: the bound is on memory).
const QUEUE: usize = 16;

/// Messages of any kind waiting for the publishing thread: a few sweeps' joint samples (24 bytes
/// each) besides the [`QUEUE`] sweeps and detections.
const JOINT_QUEUE: usize = 4096;

/// The node, made and with its publishers, before the daemon says it is ready: a configuration
/// that asks for a node that cannot start is refused at start-up, not after "listening".
pub struct Started {
    context: Context,
    node: Node,
    pubs: Publishers,
}

impl Started {
    pub fn new(cfg: &Ros2Config) -> Result<Started> {
        let (context, node, pubs) = start(cfg)?;
        Ok(Started { context, node, pubs })
    }
}

/// Runs the started node until the daemon stops. A node that fails later stops the daemon (the
/// configuration asked for it).
pub async fn run(shared: Arc<Shared>, cfg: Ros2Config, started: Started) {
    if let Err(e) = serve(&shared, &cfg, started).await {
        let msg = format!("the ROS 2 node: {e:#}");
        tracing::error!("{msg}");
        shared.fail(msg);
    }
}

async fn serve(shared: &Arc<Shared>, cfg: &Ros2Config, started: Started) -> Result<()> {
    let frame = shared.config().frame_id.clone();
    let Started {
        context,
        mut node,
        pubs,
    } = started;
    let spinner = node
        .spinner()
        .map_err(|e| anyhow!("{e:?}"))
        .context("the node's spinner")?;
    let spin = tokio::spawn(async move {
        if let Err(e) = spinner.spin().await {
            tracing::warn!("the ROS 2 node's spinner stopped: {e:?}");
        }
    });
    if let Some(m) = shared.mount().copied() {
        let data = topics::tf_static(&frame, &m, Time::from_unix_s(unix_now()));
        if let Err(e) = pubs.tf_static.publish(Encoded::new(data)) {
            tracing::warn!("/tf_static: {e:?}");
        }
    }
    let (tx, rx) = mpsc::channel::<Event>(QUEUE + JOINT_QUEUE);
    // Sweeps and detections queued: at most QUEUE of them, whatever the joint samples do.
    let heavy = Arc::new(AtomicUsize::new(0));
    let publisher = {
        let heavy = heavy.clone();
        std::thread::Builder::new()
            .name("ros2".into())
            .spawn(move || publish_loop(rx, &heavy, pubs, frame))
            .context("the ROS 2 publishing thread")?
    };
    tracing::info!(
        "ROS 2 node {}{}{} on domain {}",
        cfg.namespace,
        if cfg.namespace.ends_with('/') { "" } else { "/" },
        cfg.node,
        cfg.domain_id
    );
    let mut follow = topics::Follow::new(shared, "ROS 2 publishing").with_joints(shared);
    while let Some(event) = follow.next().await {
        let queued = match event {
            Event::Joints(_) => tx.try_send(event).is_ok(),
            event => {
                // Counted before it is sent: the thread may take it at once.
                if heavy.fetch_add(1, Ordering::SeqCst) < QUEUE && tx.try_send(event).is_ok() {
                    true
                } else {
                    heavy.fetch_sub(1, Ordering::SeqCst);
                    false
                }
            }
        };
        if !queued {
            tracing::warn!("ROS 2 publishing is behind: a message was dropped");
        }
    }
    drop(tx);
    let _ = tokio::task::spawn_blocking(move || publisher.join()).await;
    // The node's entities, and the spinner's (its parameter services), leave the participant
    // as they are dropped, which needs the participant still there: the node tells the spinner
    // to stop as it goes, the spinner is awaited, and the context goes last.
    drop(node);
    if tokio::time::timeout(std::time::Duration::from_millis(500), spin)
        .await
        .is_err()
    {
        tracing::warn!("the ROS 2 node's spinner did not stop in time");
    }
    drop(context);
    Ok(())
}

struct Publishers {
    points: Publisher<Encoded>,
    range: Publisher<Encoded>,
    joints: Publisher<Encoded>,
    detections: Publisher<Encoded>,
    markers: Publisher<Encoded>,
    tf_static: Publisher<Encoded>,
    /// `/tf`, with `publish_tf`.
    tf: Option<Publisher<Encoded>>,
}

fn qos(cfg: &Ros2Config) -> QosProfile {
    let reliability = if cfg.reliable {
        Reliability::Reliable {
            when_full: WhenFull::Wait(WAIT_WHEN_FULL),
        }
    } else {
        Reliability::BestEffort
    };
    QosProfile::publisher_default()
        .reliability(reliability)
        .durability(if cfg.transient_local {
            Durability::TransientLocal
        } else {
            Durability::Volatile
        })
        .history(History::KeepLast { depth: cfg.depth })
}

/// DDS finds its peers on the network interfaces, which Linux lists over netlink. Where netlink
/// sockets are refused (systemd's `RestrictAddressFamilies` without `AF_NETLINK`), RustDDS sees
/// no interface and no peer ever finds the node, without an error: refuse to start instead.
#[cfg(target_os = "linux")]
fn interfaces_listable() -> Result<()> {
    const AF_NETLINK: i32 = 16;
    socket2::Socket::new(socket2::Domain::from(AF_NETLINK), socket2::Type::RAW, None)
        .map(drop)
        .context(
            "cannot open a netlink socket to list the network interfaces, so DDS would find no \
             peers (under systemd, add AF_NETLINK to RestrictAddressFamilies)",
        )
}

#[cfg(not(target_os = "linux"))]
fn interfaces_listable() -> Result<()> {
    Ok(())
}

fn start(cfg: &Ros2Config) -> Result<(Context, Node, Publishers)> {
    interfaces_listable()?;
    // The patched RustDDS (vendor/rustdds) reassembles samples up to this size from DATA_FRAG
    // submessages, and holds 16 times it at most in incomplete ones, whatever a peer declares.
    ros2_client::dds::rustdds::set_max_fragmented_sample_size(cfg.max_received_sample);
    let context = Context::with_options(ContextOptions::new().domain_id(cfg.domain_id))
        .map_err(|e| anyhow!("{e:?}"))
        .with_context(|| format!("cannot join DDS domain {}", cfg.domain_id))?;
    let name = NodeName::new(&cfg.namespace, &cfg.node).map_err(|e| anyhow!("node name: {e:?}"))?;
    let mut node = context
        .new_node(name, NodeOptions::new().enable_rosout(false))
        .map_err(|e| anyhow!("{e:?}"))
        .context("cannot make the node")?;
    let qos = qos(cfg);
    // `/tf_static` as tf2's static broadcaster publishes it: reliable, transient local, the
    // latest message kept for subscribers that come later.
    let latched = QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Wait(WAIT_WHEN_FULL),
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 });
    let mut publisher = |topic: &str, ty: &str, qos: &QosProfile| -> Result<Publisher<Encoded>> {
        let (package, name) = ty.split_once("/msg/").ok_or_else(|| anyhow!("message type {ty}"))?;
        let t = node
            .create_topic(
                &Name::parse(topic).map_err(|e| anyhow!("topic {topic}: {e:?}"))?,
                MessageTypeName::new(package, name),
                qos,
            )
            .map_err(|e| anyhow!("{e:?}"))
            .with_context(|| format!("topic {topic}"))?;
        node.create_publisher::<Encoded>(&t, Some(qos.clone()))
            .map_err(|e| anyhow!("{e:?}"))
            .with_context(|| format!("publisher on {topic}"))
    };
    let pubs = Publishers {
        points: publisher(&cfg.points, ros::schema::POINT_CLOUD2, &qos)?,
        range: publisher(&cfg.range, ros::schema::IMAGE, &qos)?,
        markers: publisher(&cfg.markers, ros::schema::MARKER_ARRAY, &qos)?,
        joints: publisher(
            &cfg.joint_states,
            ros::schema::JOINT_STATE,
            &qos.clone().history(History::KeepLast {
                depth: cfg.depth.saturating_mul(JOINT_STATES_PER_SWEEP),
            }),
        )?,
        detections: publisher(&cfg.detections, ros::schema::DETECTION3D_ARRAY, &qos)?,
        tf_static: publisher("/tf_static", ros::schema::TF_MESSAGE, &latched)?,
        // As tf2's broadcaster publishes `/tf`: reliable, volatile, a sweep's transforms kept.
        tf: if cfg.publish_tf {
            let dynamic = QosProfile::publisher_default()
                .reliability(Reliability::Reliable {
                    when_full: WhenFull::Wait(WAIT_WHEN_FULL),
                })
                .durability(Durability::Volatile)
                .history(History::KeepLast {
                    depth: JOINT_STATES_PER_SWEEP,
                });
            Some(publisher("/tf", ros::schema::TF_MESSAGE, &dynamic)?)
        } else {
            None
        },
    };
    Ok((context, node, pubs))
}

fn publish_loop(mut rx: mpsc::Receiver<Event>, heavy: &AtomicUsize, pubs: Publishers, frame: String) {
    while let Some(out) = rx.blocking_recv() {
        if !matches!(out, Event::Joints(_)) {
            heavy.fetch_sub(1, Ordering::SeqCst);
        }
        match out {
            Event::Joints(j) => {
                let stamp = Time::from_unix_s(j.unix_s);
                std::thread::sleep(JOINT_STATE_PACE);
                if let Err(e) = pubs
                    .joints
                    .publish(Encoded::new(topics::joint_state(stamp, j.pan_rad, j.tilt_rad)))
                {
                    tracing::warn!("ROS 2 joint state at {:.3}: {e:?}", j.unix_s);
                }
                if let Some(tf) = &pubs.tf
                    && let Err(e) = tf.publish(Encoded::new(topics::tf_joint(stamp, j.pan_rad, j.tilt_rad)))
                {
                    tracing::warn!("ROS 2 /tf at {:.3}: {e:?}", j.unix_s);
                }
            }
            Event::Sweep(entry) => {
                let (_, data) = topics::cloud(&entry, &frame);
                if let Err(e) = pubs.points.publish(Encoded::point_cloud2(data)) {
                    tracing::warn!("ROS 2 cloud of sweep {}: {e:?}", entry.id);
                }
                let (_, data) = topics::range_image(&entry);
                if let Err(e) = pubs.range.publish(Encoded::image(data)) {
                    tracing::warn!("ROS 2 range image of sweep {}: {e:?}", entry.id);
                }
            }
            Event::Detection((entry, model, d)) => {
                let one = [(model, d)];
                let (_, data) = topics::detections(&entry, &one, &frame);
                if let Err(e) = pubs.detections.publish(Encoded::new(data)) {
                    tracing::warn!("ROS 2 detection of {} on sweep {}: {e:?}", one[0].0.name, entry.id);
                }
                let (_, data) = topics::markers(&entry, &one, &frame);
                if let Err(e) = pubs.markers.publish(Encoded::new(data)) {
                    tracing::warn!("ROS 2 markers of {} on sweep {}: {e:?}", one[0].0.name, entry.id);
                }
            }
        }
    }
}

fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::Header;
    use byteorder::LittleEndian;
    use ros2_client::dds::rustdds::{CDRSerializerAdapter, no_key::SerializerAdapter};

    /// RustDDS's CDR serializer writes an [`Encoded`] message as the bytes `crate::ros` made,
    /// with its bulk path for the cloud's data.
    #[test]
    fn an_encoded_message_serializes_to_its_own_bytes() {
        use crate::cloud::PointCloud;
        let mut cloud = PointCloud::default();
        for i in 0..7 {
            cloud.points.push([i as f32, 0.5, f32::NAN]);
        }
        cloud.width = 7;
        cloud.height = 1;
        let cdr = crate::cloud::point_cloud2(
            &cloud,
            &Header {
                stamp: Time { sec: 5, nanosec: 6 },
                frame_id: "base",
            },
        );
        let e = Encoded::point_cloud2(cdr.clone());
        assert!(e.blob.is_some());
        let bytes = |e: &Encoded| {
            <CDRSerializerAdapter<Encoded, LittleEndian> as SerializerAdapter<Encoded>>::to_bytes(e).unwrap()
        };
        assert_eq!(&bytes(&e)[..], &cdr[4..]);
        let j = ros::joint_state(&Header::default(), &topics::JOINT_NAMES, &[0.1, -0.2]);
        assert_eq!(&bytes(&Encoded::new(j.clone()))[..], &j[4..]);
        let i = ros::image_32fc1(&Header::default(), 2, 3, &[1.0, f32::NAN, 2.0, 3.0, 4.0, 5.0]);
        let e = Encoded::image(i.clone());
        assert!(e.blob.is_some());
        assert_eq!(&bytes(&e)[..], &i[4..]);
    }
}
