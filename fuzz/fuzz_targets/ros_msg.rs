//! Any bytes as a serialised ROS message: every decoder of `io::bag::cdr`, in CDR and in ROS 1
//! serialisation, the header alone, the camera model of a CameraInfo, and both image messages
//! converted to grey must return (an error or a value), never panic, hang or exhaust memory.
#![no_main]

use dvlcal::io::bag::Serialization;
use dvlcal::io::bag::cdr::*;
use dvlcal::io::bag::image::message_to_gray;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for ser in [Serialization::Cdr, Serialization::Ros1] {
        let _ = decode_header(data, ser);
        let _ = decode::<Time>(data, ser);
        let _ = decode::<Header>(data, ser);
        let _ = decode::<StringMsg>(data, ser);
        let _ = decode::<Vector3>(data, ser);
        let _ = decode::<Point>(data, ser);
        let _ = decode::<Quaternion>(data, ser);
        let _ = decode::<Pose>(data, ser);
        let _ = decode::<PoseStamped>(data, ser);
        let _ = decode::<PoseWithCovariance>(data, ser);
        let _ = decode::<PoseWithCovarianceStamped>(data, ser);
        let _ = decode::<Twist>(data, ser);
        let _ = decode::<TwistWithCovariance>(data, ser);
        let _ = decode::<TwistWithCovarianceStamped>(data, ser);
        let _ = decode::<Transform>(data, ser);
        let _ = decode::<TransformStamped>(data, ser);
        let _ = decode::<TfMessage>(data, ser);
        let _ = decode::<Odometry>(data, ser);
        let _ = decode::<Dvl>(data, ser);
        let _ = decode::<Image>(data, ser);
        let _ = decode::<CompressedImage>(data, ser);
        let _ = decode::<RegionOfInterest>(data, ser);
        if let Ok(c) = decode::<CameraInfo>(data, ser) {
            let _ = c.model();
        }
        let _ = message_to_gray(data, ser, "sensor_msgs/msg/Image");
        let _ = message_to_gray(data, ser, "sensor_msgs/CompressedImage");
    }
});
