//! `preprocess --memory-budget-gib`: a ceiling on the process's resident memory (issue 17's
//! bounded memory), kept two ways. Every thread of the parallel stages holds working memory
//! of its own, and its allocator heap keeps some of it, so the run gets no more threads than
//! fit beside what the load left resident ([`MemoryBudget::threads_within`]). And the tiled
//! cluster-tree build admits its tile jobs under the budget as they start. Each job
//! holds its tile's working data (vertex store, R-trees, heaps) while it runs; with every
//! thread on a tile of its own, those working sets add up. A job is started only when what
//! is resident now, the estimates of the jobs still running and its own estimate fit the
//! budget, or when no other job runs (so the build always goes on, one tile at a time at
//! worst). The package does not depend on it: tiles are built the same whatever runs beside
//! them, and their trees are put back in tile order.
//!
//! What is resident counts the running jobs' memory as far as they have allocated it, and
//! their estimates count it again: the double count errs on the side of the budget.

use std::sync::{Mutex, MutexGuard, PoisonError};

use citywalk_scenes::process_memory::resident_bytes;
use serde::Serialize;

/// The working memory of a tile job per building of its tile (bytes), measured on generated
/// cities (BENCHMARKS.md "The memory budget": what the peak grows by with each thread, tiles
/// of 1k and 16k buildings, less [`THREAD_HEAP_BYTES`], over the tile's buildings).
pub const TILE_WORKING_BYTES_PER_BUILDING: u64 = 1536;

/// What a worker thread holds besides its tile job, whatever the city: its allocator heap's
/// kept pages and the buffers of the per-building stages (measured as above).
pub const THREAD_HEAP_BYTES: u64 = 12 << 20;

/// What the stages hold beyond what the load left resident, on one thread, is
/// [`STAGE_FIXED_BYTES`] and this per building of the city: the occluder set's and the cluster
/// tree's working copies before they are spilled or joined (measured as above: the
/// one-thread peak above the resident city, 30k and 100k buildings).
pub const STAGE_BYTES_PER_BUILDING: u64 = 1000;

/// See [`STAGE_BYTES_PER_BUILDING`].
pub const STAGE_FIXED_BYTES: u64 = 64 << 20;

/// The estimated working memory of a tile job over `buildings` buildings.
pub fn tile_job_bytes(buildings: usize) -> u64 {
    buildings as u64 * TILE_WORKING_BYTES_PER_BUILDING
}

/// A resident-memory ceiling and the jobs admitted under it.
#[derive(Debug)]
pub struct MemoryBudget {
    /// `None`: every job is admitted at once.
    limit_bytes: Option<u64>,
    admitted: Mutex<Admitted>,
}

/// The jobs running under a budget, and what the budget did to them.
#[derive(Debug, Default)]
struct Admitted {
    jobs: usize,
    estimated_bytes: u64,
    /// The last job refused for want of memory.
    last_held_back: Option<usize>,
    report: BudgetReport,
}

/// What a budget did: the most jobs it let run at once and how many it held back.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct BudgetReport {
    pub most_jobs_at_once: usize,
    /// Jobs that waited for others to finish for want of memory (not of a free worker).
    pub jobs_held_back: usize,
}

/// A running job's place under the budget; dropped when the job is done.
#[derive(Debug)]
pub struct Admission<'a> {
    budget: &'a MemoryBudget,
    estimated_bytes: u64,
}

impl MemoryBudget {
    /// A budget of `limit_bytes` of resident memory.
    pub fn new(limit_bytes: u64) -> MemoryBudget {
        MemoryBudget {
            limit_bytes: Some(limit_bytes),
            admitted: Mutex::default(),
        }
    }

    /// No ceiling: every job is admitted at once.
    pub fn unlimited() -> MemoryBudget {
        MemoryBudget {
            limit_bytes: None,
            admitted: Mutex::default(),
        }
    }

    pub fn limit_bytes(&self) -> Option<u64> {
        self.limit_bytes
    }

    /// How many of `requested` threads (at least one) fit the budget beside what is resident
    /// now and what the stages hold for a city of `buildings` ([`STAGE_BYTES_PER_BUILDING`]),
    /// each thread beyond the first counted at [`THREAD_HEAP_BYTES`] and the working memory
    /// of a tile of `tile_buildings`.
    pub fn threads_within(
        &self,
        requested: usize,
        buildings: usize,
        tile_buildings: usize,
    ) -> usize {
        let resident = resident_bytes().0.unwrap_or(0);
        self.threads_beside(resident, requested, buildings, tile_buildings)
    }

    /// [`Self::threads_within`] with `resident` bytes resident.
    fn threads_beside(
        &self,
        resident: u64,
        requested: usize,
        buildings: usize,
        tile_buildings: usize,
    ) -> usize {
        let Some(limit) = self.limit_bytes else {
            return requested;
        };
        let per_thread = THREAD_HEAP_BYTES + tile_job_bytes(tile_buildings);
        let held = resident + STAGE_FIXED_BYTES + buildings as u64 * STAGE_BYTES_PER_BUILDING;
        let room = (limit + per_thread).saturating_sub(held);
        usize::try_from(room / per_thread)
            .unwrap_or(usize::MAX)
            .clamp(1, requested.max(1))
    }

    /// Admits job `job` of `estimated_bytes` when fewer than `workers` jobs run and it fits
    /// the budget beside them (always when none runs); `None` otherwise. It never waits: a
    /// worker that waited could hold back the very job it waits for, so whoever hands out jobs
    /// tries again as each running job finishes (see [`crate::cluster::tiled`]). Jobs are
    /// numbered so that one refused several times is counted held back once.
    pub fn try_admit(
        &self,
        job: usize,
        estimated_bytes: u64,
        workers: usize,
    ) -> Option<Admission<'_>> {
        let mut admitted = self.lock();
        if admitted.jobs > 0 {
            if admitted.jobs >= workers {
                return None;
            }
            if !self.fits(&admitted, estimated_bytes) {
                if admitted.last_held_back != Some(job) {
                    admitted.last_held_back = Some(job);
                    admitted.report.jobs_held_back += 1;
                }
                return None;
            }
        }
        admitted.jobs += 1;
        admitted.estimated_bytes += estimated_bytes;
        admitted.report.most_jobs_at_once = admitted.report.most_jobs_at_once.max(admitted.jobs);
        Some(Admission {
            budget: self,
            estimated_bytes,
        })
    }

    /// What the budget did so far.
    pub fn report(&self) -> BudgetReport {
        self.lock().report
    }

    fn fits(&self, admitted: &Admitted, estimated_bytes: u64) -> bool {
        let Some(limit) = self.limit_bytes else {
            return true;
        };
        // Off Linux nothing says what is resident: the estimates alone are counted.
        let resident = resident_bytes().0.unwrap_or(0);
        resident + admitted.estimated_bytes + estimated_bytes <= limit
    }

    fn lock(&self) -> MutexGuard<'_, Admitted> {
        self.admitted.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Drop for Admission<'_> {
    fn drop(&mut self) {
        let mut admitted = self.budget.lock();
        admitted.jobs -= 1;
        admitted.estimated_bytes -= self.estimated_bytes;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unlimited_admits_every_job_at_once() {
        let budget = MemoryBudget::unlimited();
        let jobs: Vec<_> = (0..5)
            .map(|job| budget.try_admit(job, u64::MAX / 8, 8).expect("admitted"))
            .collect();
        assert_eq!(budget.report().most_jobs_at_once, 5);
        drop(jobs);
        assert_eq!(budget.report().jobs_held_back, 0);
    }

    #[test]
    fn a_job_over_the_budget_runs_alone_and_the_next_is_held_back_until_it_is_done() {
        // Less than is resident already: nothing fits beside a running job.
        let budget = MemoryBudget::new(1);
        let first = budget
            .try_admit(0, 1 << 20, 8)
            .expect("the first job runs alone");
        assert!(budget.try_admit(1, 1 << 20, 8).is_none());
        assert!(budget.try_admit(1, 1 << 20, 8).is_none());
        drop(first);
        let second = budget.try_admit(1, 1 << 20, 8);
        assert!(second.is_some(), "the next job once none runs");
        let report = budget.report();
        assert_eq!(report.most_jobs_at_once, 1);
        assert_eq!(report.jobs_held_back, 1, "one job, refused twice");
    }

    #[test]
    fn no_more_jobs_than_workers_run_and_waiting_for_one_is_not_held_back() {
        let budget = MemoryBudget::unlimited();
        let first = budget.try_admit(0, 1, 1).expect("first");
        assert!(
            budget.try_admit(1, 1, 1).is_none(),
            "a second job on one worker"
        );
        drop(first);
        assert!(budget.try_admit(1, 1, 1).is_some());
        assert_eq!(budget.report().jobs_held_back, 0);
    }

    #[test]
    fn jobs_that_fit_run_together() {
        let resident = resident_bytes().0.unwrap_or(0);
        // Room to spare for what the tests beside this one allocate meanwhile.
        let budget = MemoryBudget::new(resident + (4 << 30));
        let a = budget.try_admit(0, 1 << 20, 8);
        let b = budget.try_admit(1, 1 << 20, 8);
        assert!(a.is_some() && b.is_some());
        assert_eq!(budget.report().most_jobs_at_once, 2);
        assert_eq!(budget.report().jobs_held_back, 0);
    }

    #[test]
    fn threads_are_as_many_as_fit_and_at_least_one() {
        let resident = 100 << 20;
        let per_thread = THREAD_HEAP_BYTES + tile_job_bytes(1000);
        let stages = STAGE_FIXED_BYTES + 10_000 * STAGE_BYTES_PER_BUILDING;
        // Room for the stages and two threads beyond the first, and half of a third.
        let budget = MemoryBudget::new(resident + stages + 2 * per_thread + per_thread / 2);
        assert_eq!(budget.threads_beside(resident, 8, 10_000, 1000), 3);
        assert_eq!(budget.threads_beside(resident, 2, 10_000, 1000), 2);
        // More resident, or a larger city, leaves room for fewer.
        assert_eq!(
            budget.threads_beside(resident + per_thread, 8, 10_000, 1000),
            2
        );
        let larger = 10_000 + (2 * per_thread / STAGE_BYTES_PER_BUILDING) as usize;
        assert_eq!(budget.threads_beside(resident, 8, larger, 1000), 1);
        assert_eq!(MemoryBudget::new(1).threads_within(8, 10_000, 1000), 1);
        assert_eq!(MemoryBudget::unlimited().threads_within(8, 10_000, 1000), 8);
    }
}
