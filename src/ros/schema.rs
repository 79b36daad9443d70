//! The `ros2msg` definitions (MCAP's schema encoding of that name, and rosbag2's): the message's
//! own fields, then every type it uses after a line of 80 `=` and `MSG: package/Type`.

const SEPARATOR: &str = "================================================================================\n";

fn with(own: &str, deps: &[(&str, &str)]) -> String {
    let mut s = own.to_string();
    for (name, def) in deps {
        s.push_str(SEPARATOR);
        s.push_str(&format!("MSG: {name}\n"));
        s.push_str(def);
    }
    s
}

const TIME: (&str, &str) = ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n");
const HEADER: (&str, &str) = ("std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id\n");
const VECTOR3: (&str, &str) = ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n");
const POINT: (&str, &str) = ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n");
const QUATERNION: (&str, &str) = (
    "geometry_msgs/Quaternion",
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
);
const POSE: (&str, &str) = (
    "geometry_msgs/Pose",
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
);

pub const POINT_CLOUD2: &str = "sensor_msgs/msg/PointCloud2";
pub fn point_cloud2() -> String {
    with(
        "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\n\
         bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
        &[
            HEADER,
            TIME,
            (
                "sensor_msgs/PointField",
                "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\n\
                 uint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\n\
                 string name\nuint32 offset\nuint8 datatype\nuint32 count\n",
            ),
        ],
    )
}

pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
pub fn joint_state() -> String {
    with(
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
        &[HEADER, TIME],
    )
}

pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
pub fn tf_message() -> String {
    with(
        "geometry_msgs/TransformStamped[] transforms\n",
        &[
            (
                "geometry_msgs/TransformStamped",
                "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
            ),
            HEADER,
            TIME,
            (
                "geometry_msgs/Transform",
                "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
            ),
            VECTOR3,
            QUATERNION,
        ],
    )
}

const COLOR: (&str, &str) = ("std_msgs/ColorRGBA", "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n");

pub const IMAGE: &str = "sensor_msgs/msg/Image";
pub fn image() -> String {
    with(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n\
         uint32 step\nuint8[] data\n",
        &[HEADER, TIME],
    )
}

pub const MARKER_ARRAY: &str = "visualization_msgs/msg/MarkerArray";
pub fn marker_array() -> String {
    with(
        "visualization_msgs/Marker[] markers\n",
        &[
            (
                "visualization_msgs/Marker",
                "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n\
                 int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n\
                 int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\n\
                 int32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n\
                 std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n\
                 geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n\
                 builtin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\n\
                 std_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\n\
                 visualization_msgs/UVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\n\
                 visualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n",
            ),
            HEADER,
            TIME,
            POSE,
            POINT,
            QUATERNION,
            VECTOR3,
            COLOR,
            ("builtin_interfaces/Duration", "int32 sec\nuint32 nanosec\n"),
            (
                "sensor_msgs/CompressedImage",
                "std_msgs/Header header\nstring format\nuint8[] data\n",
            ),
            ("visualization_msgs/UVCoordinate", "float32 u\nfloat32 v\n"),
            ("visualization_msgs/MeshFile", "string filename\nuint8[] data\n"),
        ],
    )
}

pub const DETECTION3D_ARRAY: &str = "vision_msgs/msg/Detection3DArray";
pub fn detection3d_array() -> String {
    with(
        "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n",
        &[
            HEADER,
            TIME,
            (
                "vision_msgs/Detection3D",
                "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n\
                 vision_msgs/BoundingBox3D bbox\nstring id\n",
            ),
            (
                "vision_msgs/ObjectHypothesisWithPose",
                "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n",
            ),
            ("vision_msgs/ObjectHypothesis", "string class_id\nfloat64 score\n"),
            (
                "geometry_msgs/PoseWithCovariance",
                "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
            ),
            POSE,
            POINT,
            QUATERNION,
            (
                "vision_msgs/BoundingBox3D",
                "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
            ),
            VECTOR3,
        ],
    )
}
