//! The message types dvlcal reads, each declared by its field list (see [`super::declare`] for
//! how a field is written); the decoders read both serialisations.

use super::declare::{ros_messages, ros_messages_with_view};
use super::header::{HEADER_MIN, Header};

ros_messages! {
    /// `std_msgs/msg/String`: `string data`.
    #[derive(Clone, Debug, Default, PartialEq, Eq)]
    pub struct StringMsg = "std_msgs/msg/String" {
        /// The text.
        data: String = string("String.data"),
    }

    /// `geometry_msgs/msg/Vector3`: `float64 x, y, z`.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct Vector3 = "geometry_msgs/msg/Vector3" {
        /// x.
        x: f64 = f64("Vector3"),
        /// y.
        y: f64 = f64("Vector3"),
        /// z.
        z: f64 = f64("Vector3"),
    }

    /// `geometry_msgs/msg/Point`: `float64 x, y, z`.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct Point = "geometry_msgs/msg/Point" {
        /// x.
        x: f64 = f64("Point"),
        /// y.
        y: f64 = f64("Point"),
        /// z.
        z: f64 = f64("Point"),
    }

    /// `geometry_msgs/msg/Quaternion`: `float64 x, y, z, w` (the scalar part last).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Quaternion = "geometry_msgs/msg/Quaternion" {
        /// x.
        x: f64 = f64("Quaternion"),
        /// y.
        y: f64 = f64("Quaternion"),
        /// z.
        z: f64 = f64("Quaternion"),
        /// w, the scalar part.
        w: f64 = f64("Quaternion"),
    }

    /// `geometry_msgs/msg/Pose`: `Point position`, `Quaternion orientation`.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct Pose = "geometry_msgs/msg/Pose" {
        /// The position.
        position: Point = message,
        /// The orientation.
        orientation: Quaternion = message,
    }

    /// `geometry_msgs/msg/PoseStamped`: `std_msgs/Header header`, `Pose pose`.
    #[derive(Clone, Debug, Default, PartialEq)]
    pub struct PoseStamped = "geometry_msgs/msg/PoseStamped" {
        /// Stamp and frame.
        header: Header = message,
        /// The pose.
        pose: Pose = message,
    }

    /// `geometry_msgs/msg/PoseWithCovariance`: `Pose pose`, `float64[36] covariance` (row-major
    /// 6x6 over x, y, z and rotations about x, y, z).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct PoseWithCovariance = "geometry_msgs/msg/PoseWithCovariance" {
        /// The pose.
        pose: Pose = message,
        /// Row-major 6x6 covariance.
        covariance: [f64; 36] = f64_array("PoseWithCovariance.covariance"),
    }

    /// `geometry_msgs/msg/PoseWithCovarianceStamped`: `std_msgs/Header header`,
    /// `PoseWithCovariance pose`.
    #[derive(Clone, Debug, PartialEq)]
    pub struct PoseWithCovarianceStamped = "geometry_msgs/msg/PoseWithCovarianceStamped" {
        /// Stamp and frame.
        header: Header = message,
        /// The pose and its covariance.
        pose: PoseWithCovariance = message,
    }

    /// `geometry_msgs/msg/Twist`: `Vector3 linear`, `Vector3 angular`.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct Twist = "geometry_msgs/msg/Twist" {
        /// Linear velocity.
        linear: Vector3 = message,
        /// Angular velocity.
        angular: Vector3 = message,
    }

    /// `geometry_msgs/msg/TwistWithCovariance`: `Twist twist`, `float64[36] covariance`
    /// (row-major 6x6).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct TwistWithCovariance = "geometry_msgs/msg/TwistWithCovariance" {
        /// The twist.
        twist: Twist = message,
        /// Row-major 6x6 covariance.
        covariance: [f64; 36] = f64_array("TwistWithCovariance.covariance"),
    }

    /// `geometry_msgs/msg/TwistWithCovarianceStamped`: `std_msgs/Header header`,
    /// `TwistWithCovariance twist`.
    #[derive(Clone, Debug, PartialEq)]
    pub struct TwistWithCovarianceStamped = "geometry_msgs/msg/TwistWithCovarianceStamped" {
        /// Stamp and frame.
        header: Header = message,
        /// The twist and its covariance.
        twist: TwistWithCovariance = message,
    }

    /// `geometry_msgs/msg/Transform`: `Vector3 translation`, `Quaternion rotation`.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct Transform = "geometry_msgs/msg/Transform" {
        /// The translation.
        translation: Vector3 = message,
        /// The rotation.
        rotation: Quaternion = message,
    }

    /// `geometry_msgs/msg/TransformStamped`: `std_msgs/Header header`, `string child_frame_id`,
    /// `Transform transform` (the pose of `child_frame_id` in `header.frame_id`).
    #[derive(Clone, Debug, Default, PartialEq)]
    pub struct TransformStamped = "geometry_msgs/msg/TransformStamped" {
        /// Stamp and parent frame.
        header: Header = message,
        /// The child frame.
        child_frame_id: String = string("TransformStamped.child_frame_id"),
        /// The transform.
        transform: Transform = message,
    }

    /// `tf2_msgs/msg/TFMessage`: `geometry_msgs/TransformStamped[] transforms`.
    #[derive(Clone, Debug, Default, PartialEq)]
    pub struct TfMessage = "tf2_msgs/msg/TFMessage" {
        /// The transforms.
        // Header, a child frame's length and seven float64s at the least.
        transforms: Vec<TransformStamped> =
            message_seq("TFMessage.transforms", HEADER_MIN + 4 + 56),
    }

    /// `nav_msgs/msg/Odometry`: `std_msgs/Header header`, `string child_frame_id`,
    /// `geometry_msgs/PoseWithCovariance pose` (in `header.frame_id`),
    /// `geometry_msgs/TwistWithCovariance twist` (in `child_frame_id`).
    #[derive(Clone, Debug, PartialEq)]
    pub struct Odometry = "nav_msgs/msg/Odometry" {
        /// Stamp and the pose's frame.
        header: Header = message,
        /// The twist's frame.
        child_frame_id: String = string("Odometry.child_frame_id"),
        /// The pose and its covariance.
        pose: PoseWithCovariance = message,
        /// The twist and its covariance.
        twist: TwistWithCovariance = message,
    }

    /// `marine_acoustic_msgs/msg/Dvl` (apl-ocean-engineering/marine_msgs), the report of Water
    /// Linked's ROS 2 driver: `std_msgs/Header header`, `uint8 velocity_mode`, `uint8 dvl_type`,
    /// `geometry_msgs/Vector3 velocity`, `float64[9] velocity_covar`, `float64 altitude`,
    /// `float64 course_gnd`, `float64 speed_gnd`, `uint8 num_good_beams`, `float32 sound_speed`,
    /// `bool beam_ranges_valid`, `bool beam_velocities_valid`,
    /// `geometry_msgs/Vector3[4] beam_unit_vec`, `float64[4] range`, `float32[4] range_covar`,
    /// `float32[4] beam_quality`, `float32[4] beam_velocity`, `float32[4] beam_velocity_covar`.
    /// (The message's constants, such as the mode and type codes, are not serialised.)
    #[derive(Clone, Debug, PartialEq)]
    pub struct Dvl = "marine_acoustic_msgs/msg/Dvl" {
        /// Stamp (the time of validity, for Water Linked's driver) and frame.
        header: Header = message,
        /// Bottom track, water track or both (the message's `DVL_MODE_*` codes).
        velocity_mode: u8 = u8("Dvl.velocity_mode"),
        /// The kind of DVL (the message's `DVL_TYPE_*` codes).
        dvl_type: u8 = u8("Dvl.dvl_type"),
        /// The velocity, m/s.
        velocity: Vector3 = message,
        /// Row-major 3x3 covariance of the velocity.
        velocity_covar: [f64; 9] = f64_array("Dvl.velocity_covar"),
        /// Altitude above the bottom, m.
        altitude: f64 = f64("Dvl.altitude"),
        /// Course over ground.
        course_gnd: f64 = f64("Dvl.course_gnd"),
        /// Speed over ground.
        speed_gnd: f64 = f64("Dvl.speed_gnd"),
        /// How many beams were good.
        num_good_beams: u8 = u8("Dvl.num_good_beams"),
        /// Speed of sound, m/s.
        sound_speed: f32 = f32("Dvl.sound_speed"),
        /// Whether the beam ranges are valid.
        beam_ranges_valid: bool = bool("Dvl.beam_ranges_valid"),
        /// Whether the beam velocities are valid (Water Linked: the velocity is valid).
        beam_velocities_valid: bool = bool("Dvl.beam_velocities_valid"),
        /// Unit vector of each beam.
        beam_unit_vec: [Vector3; 4] = messages,
        /// Range along each beam, m.
        range: [f64; 4] = f64_array("Dvl.range"),
        /// Variance of each range.
        range_covar: [f32; 4] = f32_array("Dvl.range_covar"),
        /// Quality of each beam.
        beam_quality: [f32; 4] = f32_array("Dvl.beam_quality"),
        /// Velocity along each beam, m/s.
        beam_velocity: [f32; 4] = f32_array("Dvl.beam_velocity"),
        /// Variance of each beam velocity.
        beam_velocity_covar: [f32; 4] = f32_array("Dvl.beam_velocity_covar"),
    }

    /// `sensor_msgs/msg/Imu` (ROS 1 `sensor_msgs/Imu`, the same fields):
    /// `std_msgs/Header header`, `geometry_msgs/Quaternion orientation`,
    /// `float64[9] orientation_covariance`, `geometry_msgs/Vector3 angular_velocity`,
    /// `float64[9] angular_velocity_covariance`, `geometry_msgs/Vector3 linear_acceleration`,
    /// `float64[9] linear_acceleration_covariance`. The covariances are row-major 3x3 about the
    /// x, y, z axes; by ROS's convention all zeros means "unknown" and a first element of -1
    /// means "not provided" (an IMU without an orientation estimate says so in
    /// `orientation_covariance[0]`).
    #[derive(Clone, Debug, PartialEq)]
    pub struct Imu = "sensor_msgs/msg/Imu" {
        /// Stamp (the time of the measurement) and the IMU's frame.
        header: Header = message,
        /// The IMU's orientation estimate, when it gives one.
        orientation: Quaternion = message,
        /// Row-major 3x3 covariance of the orientation, rad^2.
        orientation_covariance: [f64; 9] = f64_array("Imu.orientation_covariance"),
        /// Angular velocity, rad/s, IMU frame.
        angular_velocity: Vector3 = message,
        /// Row-major 3x3 covariance of the angular velocity, (rad/s)^2.
        angular_velocity_covariance: [f64; 9] = f64_array("Imu.angular_velocity_covariance"),
        /// Linear acceleration (specific force: gravity included), m/s^2, IMU frame.
        linear_acceleration: Vector3 = message,
        /// Row-major 3x3 covariance of the linear acceleration, (m/s^2)^2.
        linear_acceleration_covariance: [f64; 9] =
            f64_array("Imu.linear_acceleration_covariance"),
    }

    /// `sensor_msgs/msg/RegionOfInterest`: `uint32 x_offset`, `uint32 y_offset`, `uint32 height`,
    /// `uint32 width`, `bool do_rectify`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
    pub struct RegionOfInterest = "sensor_msgs/msg/RegionOfInterest" {
        /// Leftmost column.
        x_offset: u32 = u32("RegionOfInterest.x_offset"),
        /// Topmost row.
        y_offset: u32 = u32("RegionOfInterest.y_offset"),
        /// Rows.
        height: u32 = u32("RegionOfInterest.height"),
        /// Columns.
        width: u32 = u32("RegionOfInterest.width"),
        /// Whether the region is to be rectified.
        do_rectify: bool = bool("RegionOfInterest.do_rectify"),
    }

    /// `sensor_msgs/msg/CameraInfo`: `std_msgs/Header header`, `uint32 height`, `uint32 width`,
    /// `string distortion_model`, `float64[] d`, `float64[9] k`, `float64[9] r`,
    /// `float64[12] p`, `uint32 binning_x`, `uint32 binning_y`, `RegionOfInterest roi`. ROS 1
    /// names the four matrices `D`, `K`, `R`, `P`, with the same layout.
    #[derive(Clone, Debug, PartialEq)]
    pub struct CameraInfo = "sensor_msgs/msg/CameraInfo" {
        /// Stamp and camera frame.
        header: Header = message,
        /// Rows of the calibrated image.
        height: u32 = u32("CameraInfo.height"),
        /// Columns of the calibrated image.
        width: u32 = u32("CameraInfo.width"),
        /// The distortion model (`plumb_bob`, `rational_polynomial`, `equidistant`).
        distortion_model: String = string("CameraInfo.distortion_model"),
        /// Distortion coefficients (k1, k2, t1, t2, k3 for `plumb_bob`).
        d: Vec<f64> = f64_seq("CameraInfo.d"),
        /// Row-major 3x3 intrinsic matrix.
        k: [f64; 9] = f64_array("CameraInfo.k"),
        /// Row-major 3x3 rectification rotation (stereo).
        r: [f64; 9] = f64_array("CameraInfo.r"),
        /// Row-major 3x4 projection matrix.
        p: [f64; 12] = f64_array("CameraInfo.p"),
        /// Horizontal binning (0 or 1: none).
        binning_x: u32 = u32("CameraInfo.binning_x"),
        /// Vertical binning (0 or 1: none).
        binning_y: u32 = u32("CameraInfo.binning_y"),
        /// The region of interest (all zeros: the whole image).
        roi: RegionOfInterest = message,
    }
}

impl Default for Quaternion {
    /// The identity, as the message's own default (`w = 1`).
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

ros_messages_with_view! {
    /// `sensor_msgs/msg/Image`: `std_msgs/Header header`, `uint32 height`, `uint32 width`,
    /// `string encoding`, `uint8 is_bigendian`, `uint32 step`, `uint8[] data`.
    #[derive(Clone, Debug, Default, PartialEq, Eq)]
    pub struct Image = "sensor_msgs/msg/Image" {
        /// Stamp (of the exposure) and camera frame.
        header: Header = message,
        /// Rows.
        height: u32 = u32("Image.height"),
        /// Columns.
        width: u32 = u32("Image.width"),
        /// Pixel encoding (`mono8`, `bgr8`, `rgb8`, `mono16`, ...).
        encoding: String = string("Image.encoding"),
        /// Whether multi-byte pixels are big-endian (as sent: any nonzero value means yes).
        is_bigendian: u8 = u8("Image.is_bigendian"),
        /// Bytes per row.
        step: u32 = u32("Image.step"),
    }
    /// A `sensor_msgs/Image` whose pixels are borrowed from the serialised message, so that
    /// converting an image does not copy megabytes first. The fields are those of [`Image`].
    #[derive(Clone, Debug, Default, PartialEq, Eq)]
    pub struct ImageView<'a>, copied by to_image {
        /// The pixels, `step * height` bytes in a well-formed message.
        data = byte_seq("Image.data"),
    }

    /// `sensor_msgs/msg/CompressedImage`: `std_msgs/Header header`, `string format`,
    /// `uint8[] data`.
    #[derive(Clone, Debug, Default, PartialEq, Eq)]
    pub struct CompressedImage = "sensor_msgs/msg/CompressedImage" {
        /// Stamp and camera frame.
        header: Header = message,
        /// The format (`jpeg`, `png`, or image_transport's `bgr8; jpeg compressed bgr8`).
        format: String = string("CompressedImage.format"),
    }
    /// A `sensor_msgs/CompressedImage` whose file bytes are borrowed from the serialised message.
    /// The fields are those of [`CompressedImage`].
    #[derive(Clone, Debug, Default, PartialEq, Eq)]
    pub struct CompressedImageView<'a>, copied by to_compressed_image {
        /// The compressed image file.
        data = byte_seq("CompressedImage.data"),
    }
}
