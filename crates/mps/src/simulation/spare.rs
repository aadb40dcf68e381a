//! The step's spare arrays ([`SpareArrays`]), shared by the stages through `&self`: a stage
//! takes the array it fills from here and the step gives it back when it is done with it,
//! so a warm step allocates nothing (issue 15; docs/decisions.md, "A step without
//! allocations").

use crate::particles::{SpareArrays, Spared};
use std::sync::{Mutex, MutexGuard};

/// The spare arrays behind a lock.
#[derive(Debug, Default)]
pub(super) struct Spare<const D: usize> {
    arrays: Mutex<SpareArrays<D>>,
}

impl<const D: usize> Spare<D> {
    /// The arrays themselves.
    pub fn lock(&self) -> MutexGuard<'_, SpareArrays<D>> {
        self.arrays.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A spare array (empty, with the capacity it had), or a new one.
    pub fn take<T: Spared<D>>(&self) -> Vec<T> {
        self.lock().take()
    }

    /// Keeps `v`'s memory for a later [`Spare::take`].
    pub fn give<T: Spared<D>>(&self, v: Vec<T>) {
        self.lock().give(v)
    }
}
