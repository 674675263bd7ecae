//! Bag containers. Each reader gives connections (topic, message type) and the serialised
//! messages of the ones asked for, in file order; decoding the messages is left to the format
//! that needs them (the DVL messages in [`crate::io::dvl`]); [`cdr`] decodes the
//! messages of ROS 2 bags.

pub mod cdr;
pub mod ros1;
