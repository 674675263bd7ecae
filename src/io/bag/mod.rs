//! Bag containers. Each reader gives connections (topic, message type) and the serialised
//! messages of the ones asked for, in file order; decoding the messages is left to the format
//! that needs them (the DVL messages in [`crate::io::dvl`]).

pub mod ros1;
