//! The bag options every dataset command shares, and `dvlcal bag-info`: a bag's topics, types,
//! counts, rates and spans, and the part dvlcal would give each.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use dvlcal::io::bag::info::bag_info;
use dvlcal::io::bag::roles::{BagOptions, BagTime};

/// Which topics of a bag play which part (by default chosen from the message types).
#[derive(Args, Debug, Clone, Default)]
pub struct BagArgs {
    /// Image topics of a bag, cam0 first: one topic, or LEFT,RIGHT (default: the
    /// sensor_msgs/Image or CompressedImage topics, paired by name).
    #[arg(
        long,
        value_name = "L[,R]",
        value_delimiter = ',',
        conflicts_with = "pose_topic"
    )]
    pub image_topics: Option<Vec<String>>,
    /// Pose topic of a bag (PoseStamped, PoseWithCovarianceStamped, TransformStamped,
    /// Odometry, or /tf with --pose-frame): T_world_cam. Without it the poses come from the
    /// bag's images when it has any; with it from this topic, images or not.
    #[arg(long, value_name = "TOPIC")]
    pub pose_topic: Option<String>,
    /// Child frame whose transforms on a tf2_msgs/TFMessage topic are the camera's poses.
    #[arg(long, value_name = "FRAME")]
    pub pose_frame: Option<String>,
    /// IMU topic of a bag (sensor_msgs/Imu), when it holds more than one: calibrate reads the
    /// IMU from it (noise from --imu-noise), bag-info labels it.
    #[arg(long, value_name = "TOPIC")]
    pub imu_topic: Option<String>,
    /// Times of a bag's messages: header (header.stamp; a zero stamp falls back to the record
    /// time, with a warning) or record (when the recorder received them; for the DVL this is
    /// --dvl-time host).
    #[arg(long, value_name = "T", default_value = "header")]
    pub bag_time: BagTime,
}

impl BagArgs {
    /// The library's options, with the DVL topic given elsewhere (`--dvl-topic`).
    pub fn options(&self, dvl_topic: Option<String>) -> BagOptions {
        BagOptions {
            image_topics: self.image_topics.clone(),
            dvl_topic,
            pose_topic: self.pose_topic.clone(),
            pose_frame: self.pose_frame.clone(),
            imu_topic: self.imu_topic.clone(),
            time: self.bag_time,
        }
    }
}

/// The bag options of the commands that read a bag's images only (no pose or DVL topics).
#[derive(Args, Debug, Clone, Default)]
pub struct ImageBagArgs {
    /// Image topics of a bag, cam0 first: one topic, or LEFT,RIGHT (default: the
    /// sensor_msgs/Image or CompressedImage topics, paired by name).
    #[arg(long, value_name = "L[,R]", value_delimiter = ',')]
    pub image_topics: Option<Vec<String>>,
    /// Times of a bag's images: header (header.stamp; a zero stamp falls back to the record
    /// time, with a warning) or record (when the recorder received them).
    #[arg(long, value_name = "T", default_value = "header")]
    pub bag_time: BagTime,
}

impl ImageBagArgs {
    /// The library's options: the image topics and their time, no pose or DVL topic.
    pub fn options(&self) -> BagOptions {
        BagOptions::images_only(self.image_topics.clone(), self.bag_time)
    }
}

#[derive(Args, Debug)]
pub struct BagInfoArgs {
    /// The bag: a ROS 1 .bag, a ROS 2 .mcap or .db3, or a ROS 2 bag folder (metadata.yaml).
    pub bag: PathBuf,
    /// DVL topic, when the types leave a choice.
    #[arg(long, value_name = "TOPIC")]
    pub dvl_topic: Option<String>,
    #[command(flatten)]
    pub bag_args: BagArgs,
}

pub fn run(a: BagInfoArgs) -> Result<()> {
    let info = bag_info(&a.bag, &a.bag_args.options(a.dvl_topic.clone()))?;
    // A closed pipe (`dvlcal bag-info B | head`) is not an error.
    match std::io::stdout().lock().write_all(info.render().as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
