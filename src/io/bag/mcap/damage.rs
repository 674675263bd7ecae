//! What a damaged chunk cost, as told to the user.

/// A chunk that was damaged: the Message Index records after it tell what it cost.
pub(super) struct Damaged {
    pub(super) offset: u64,
    pub(super) why: String,
    /// Messages of the wanted channels handed out before the damage.
    pub(super) delivered: u64,
    /// Messages the index after the chunk lists: all, and of the wanted channels.
    pub(super) listed: u64,
    pub(super) listed_wanted: u64,
    pub(super) indexed: bool,
}

impl Damaged {
    /// What the damage cost; `counting` when messages were being read (not only topics).
    pub(super) fn describe(&self, counting: bool) -> String {
        let before = if self.delivered > 0 {
            format!(" ({} read before the damage)", self.delivered)
        } else {
            String::new()
        };
        if !counting {
            let listed = if self.indexed {
                format!(" (its index lists {} messages)", self.listed)
            } else {
                String::new()
            };
            format!(
                "the chunk at byte {} {}{listed}: topics declared only in it are missing",
                self.offset, self.why
            )
        } else if self.indexed {
            format!(
                "the chunk at byte {} {}: {} messages of the topics read are lost{before} (its \
                 index lists {} messages in all)",
                self.offset,
                self.why,
                self.listed_wanted.saturating_sub(self.delivered),
                self.listed
            )
        } else {
            format!(
                "the chunk at byte {} {}: its messages are lost{before} (no index after it says \
                 how many)",
                self.offset, self.why
            )
        }
    }
}
