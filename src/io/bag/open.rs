//! A bag opened as a dataset: the [`Bag`] with the part each of its topics plays
//! ([`crate::io::bag::roles`]), and the times its messages are placed at.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::bag::roles::{self, BagOptions, BagTime, Roles};
use crate::io::bag::{Bag, Topic};

/// A bag opened, with the parts its topics play.
#[derive(Debug)]
pub struct OpenBag {
    /// The bag.
    pub bag: Bag,
    /// The parts its topics play.
    pub roles: Roles,
    /// The options the roles were chosen with.
    pub options: BagOptions,
}

impl OpenBag {
    /// Opens `path` and gives its topics their parts.
    pub fn open(path: &Path, options: &BagOptions) -> Result<OpenBag> {
        let bag = Bag::open(path)?;
        let roles = roles::assign(bag.topics(), options)
            .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
        Ok(OpenBag {
            bag,
            roles,
            options: options.clone(),
        })
    }

    /// The bag's path.
    pub fn path(&self) -> &Path {
        self.bag.path()
    }

    /// The topic with index `i` (an index of [`Bag::topics`]).
    pub fn topic(&self, i: usize) -> &Topic {
        &self.bag.topics()[i]
    }

    /// The topics with their types, for error messages.
    pub fn topic_list(&self) -> String {
        roles::topic_list(self.bag.topics())
    }
}

/// A time in nanoseconds from a header stamp and a record time, as `time` asks: the stamp, or
/// the record time when the stamp is zero (counted in `zero`) or when record times are asked
/// for.
pub(crate) fn message_time(stamp_ns: i64, record_ns: i64, time: BagTime, zero: &mut usize) -> i64 {
    match time {
        BagTime::Record => record_ns,
        BagTime::Header if stamp_ns == 0 => {
            *zero += 1;
            record_ns
        }
        BagTime::Header => stamp_ns,
    }
}

/// How many unreadable messages a listing names (the rest are counted).
pub(crate) const LISTED: usize = 10;
