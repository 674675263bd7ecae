//! The IMU of a bag: when no IMU stream is named or in the folder, a bag of the dataset (the
//! one giving the camera data, else the DVL's) that holds a `sensor_msgs/Imu` topic
//! (`--imu-topic`, or the only one) gives it.

use crate::error::Result;
use crate::io::bag::imu::read_imu_from_bag;
use crate::io::bag::is_bag;
use crate::io::bag::open::OpenBag;
use crate::io::dataset::DatasetFiles;
use crate::io::imu::{ImuLog, imu_log_of};
use crate::time::Epoch;

/// The epoch of the IMU topic of the bag `ob` (the whole second of its first usable sample),
/// for a run without camera data whose times count from the IMU's; `None` without an IMU topic.
pub fn imu_epoch(ob: &OpenBag) -> Result<Option<Epoch>> {
    if ob.roles.imu.is_none() {
        return Ok(None);
    }
    let (_, summary) = read_imu_from_bag(&ob.bag, &ob.options)?;
    Ok(Some(summary.epoch))
}

/// The IMU stream of the dataset's bag, on `epoch`: `None` when no input is a bag or the bag
/// has no (single) Imu topic; the reader's error inside when the topic gives no usable stream
/// (the caller makes it a note). What the reading found (the topic, skipped, out-of-order and
/// repeated messages) goes into `notes`, as the bag's other readers do.
pub fn imu_from_bag(
    files: &DatasetFiles,
    epoch: Epoch,
    notes: &mut Vec<String>,
) -> Result<Option<Result<ImuLog>>> {
    let bag = files
        .bag
        .as_deref()
        .or(files.dvl.as_deref().filter(|p| is_bag(p)));
    let Some(bag) = bag else {
        return Ok(None);
    };
    let ob = OpenBag::open(bag, &files.bag_options)?;
    if ob.roles.imu.is_none() {
        return Ok(None);
    }
    let read = read_imu_from_bag(&ob.bag, &files.bag_options).and_then(|(mut samples, s)| {
        notes.push(format!(
            "IMU from {} in {}: {} of {} messages used",
            s.source,
            bag.display(),
            s.samples,
            s.messages
        ));
        notes.extend(s.warnings);
        // The bag's samples count from its own epoch: moved onto the dataset's.
        let shift = (s.epoch.sec - epoch.sec) as f64;
        samples.iter_mut().for_each(|x| x.t += shift);
        imu_log_of(bag, epoch, samples)
    });
    Ok(Some(read))
}
