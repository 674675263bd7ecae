//! File formats in and out. Nothing here estimates anything.
