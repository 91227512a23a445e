//! Progress of long work, reported through a trait so that the library draws nothing itself:
//! the binary shows it as a terminal bar, library callers and tests pass [`NoProgress`].

/// Where a progressive render reports how far it is.
pub trait Progress: Sync {
    /// The work's length: passes, or milliseconds of a time budget.
    fn set_length(&self, len: u64);
    /// The work done so far, in the units of [`Progress::set_length`].
    fn set_position(&self, pos: u64);
    /// The work is over (a bar clears itself).
    fn finish(&self) {}
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn set_length(&self, _: u64) {}
    fn set_position(&self, _: u64) {}
}
