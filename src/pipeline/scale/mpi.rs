//! `mpirun -np N optbench run SUITE` (feature `mpi`): the trials of the plan are spread
//! over the ranks and rank 0 writes the results, identical to a single-process run.
//!
//! Rank 0 coordinates: it validates the suite, opens the progress log (so `--resume` and
//! `--shard` work as in one process), and hands out plan positions one at a time to
//! whichever rank asks next (dynamic load balancing: trials of different optimizers take
//! very different times). It also runs trials itself on a second thread; only its main
//! thread calls MPI (`MPI_THREAD_FUNNELED`). Every result comes back as the record's JSON
//! (bit-exact floats), is appended to `progress.jsonl` the moment it arrives, and the
//! records are put in plan order before anything is written, so neither the number of
//! ranks nor the order in which they finish changes a byte of `summary.json`.
//!
//! Every rank reads the suite itself, so the suite file (and any recording it names) must be
//! readable at the same path on every node.

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::pipeline::run::{RunRequest, finish, open_log, prepare, run as run_local};
use crate::pipeline::runner::run_planned;
use ::mpi::Threading;
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;
use std::collections::{HashMap, VecDeque};
use std::time::Duration;

/// Worker -> rank 0: 8-byte little-endian plan position, then the record's JSON (position
/// [`NONE`]: no result yet, just asking for work).
const TAG_RESULT: i32 = 1;
/// Rank 0 -> worker: 8-byte plan position to run, or [`NONE`] to stop.
const TAG_TASK: i32 = 2;
const NONE: u64 = u64::MAX;

/// Whether this process was started by an MPI launcher (Open MPI, MPICH/Hydra, PMIx, Slurm
/// PMI), so that a plain `optbench run` never initialises MPI.
pub fn launched_by_mpirun() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// Runs the request as one rank of an MPI job; only rank 0 returns text to print.
pub fn run(req: &RunRequest) -> Result<String> {
    let (universe, _) = ::mpi::initialize_with_threading(Threading::Funneled)
        .ok_or_else(|| Error::Input("MPI was initialised twice".into()))?;
    let world = universe.world();
    if world.size() == 1 {
        return run_local(req);
    }
    if world.rank() == 0 {
        coordinate(req, &world)
    } else {
        if let Err(e) = work(req, &world) {
            // Rank 0 would wait for this rank forever: end the whole job.
            eprintln!("error (rank {}): {e}", world.rank());
            world.abort(e.exit_code());
        }
        Ok(String::new())
    }
}

fn send_task(world: &SimpleCommunicator, rank: i32, task: u64) {
    world
        .process_at_rank(rank)
        .send_with_tag(&task.to_le_bytes()[..], TAG_TASK);
}

fn work(req: &RunRequest, world: &SimpleCommunicator) -> Result<()> {
    let p = prepare(req)?;
    let root = world.process_at_rank(0);
    let mut message = NONE.to_le_bytes().to_vec();
    loop {
        root.send_with_tag(&message[..], TAG_RESULT);
        let (task, _) = root.receive_vec_with_tag::<u8>(TAG_TASK);
        let i = u64::from_le_bytes(task[..8].try_into().expect("8-byte task"));
        if i == NONE {
            return Ok(());
        }
        let t = p.plan.get(i as usize).ok_or_else(|| {
            Error::Input(format!(
                "rank 0 asked for trial {i} of a plan of {}: do all ranks read the same suite?",
                p.plan.len()
            ))
        })?;
        let record = run_planned(&p.suite, t);
        message = i.to_le_bytes().to_vec();
        serde_json::to_writer(&mut message, &record).expect("serialisable");
    }
}

fn coordinate(req: &RunRequest, world: &SimpleCommunicator) -> Result<String> {
    let started = std::time::SystemTime::now();
    let size = world.size();
    let prepared = prepare(req).and_then(|p| {
        let (log, done) = open_log(&p, req.resume, req.force_resume)?;
        Ok((p, log, done))
    });
    let (p, log, mut done) = match prepared {
        Ok(x) => x,
        Err(e) => {
            for r in 1..size {
                send_task(world, r, NONE);
            }
            return Err(e);
        }
    };
    let mut todo: VecDeque<usize> = (0..p.plan.len())
        .filter(|&i| !done.contains_key(&p.keys[i]))
        .collect();
    let total = todo.len();
    let mut fresh: HashMap<usize, TrialRecord> = HashMap::new();
    let mut failure: Option<Error> = None;
    std::thread::scope(|scope| {
        let (task_tx, task_rx) = crossbeam_channel::unbounded::<usize>();
        let (result_tx, result_rx) = crossbeam_channel::unbounded::<(usize, TrialRecord)>();
        let (suite, plan) = (&p.suite, &p.plan);
        std::thread::Builder::new()
            .name("mpi-rank0-trials".into())
            .spawn_scoped(scope, move || {
                for i in task_rx {
                    if result_tx.send((i, run_planned(suite, &plan[i]))).is_err() {
                        break;
                    }
                }
            })
            .expect("spawn the rank-0 trial thread");
        let mut store = |i: usize, r: TrialRecord, failure: &mut Option<Error>| {
            if let Err(e) = log.append(&p.keys[i], &r) {
                failure.get_or_insert(e);
            }
            fresh.insert(i, r);
        };
        let mut local_busy = false;
        let mut remote_active = size - 1;
        let mut received = 0usize;
        while received < total || remote_active > 0 {
            let mut idle = true;
            if !local_busy && let Some(i) = todo.pop_front() {
                task_tx.send(i).expect("rank-0 trial thread alive");
                local_busy = true;
            }
            if let Ok((i, r)) = result_rx.try_recv() {
                store(i, r, &mut failure);
                received += 1;
                local_busy = false;
                idle = false;
            }
            if let Some(status) = world.any_process().immediate_probe_with_tag(TAG_RESULT) {
                idle = false;
                let src = status.source_rank();
                let (bytes, _) = world
                    .process_at_rank(src)
                    .receive_vec_with_tag::<u8>(TAG_RESULT);
                let i = u64::from_le_bytes(bytes[..8].try_into().expect("8-byte position"));
                if i != NONE {
                    match serde_json::from_slice::<TrialRecord>(&bytes[8..]) {
                        Ok(r) => store(i as usize, r, &mut failure),
                        Err(e) => {
                            failure.get_or_insert(Error::Input(format!(
                                "rank {src} sent an unreadable record: {e}"
                            )));
                        }
                    }
                    received += 1;
                }
                match todo.pop_front() {
                    Some(next) => send_task(world, src, next as u64),
                    None => {
                        send_task(world, src, NONE);
                        remote_active -= 1;
                    }
                }
            }
            if idle {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        drop(task_tx);
    });
    if let Some(e) = failure {
        return Err(e);
    }
    let reused = p.plan.len() - total;
    let records: Vec<TrialRecord> = (0..p.plan.len())
        .map(|i| {
            done.remove(&p.keys[i])
                .or_else(|| fresh.remove(&i))
                .expect("every planned trial finished")
        })
        .collect();
    let provenance = crate::pipeline::store::Provenance::new(&p.suite, size as usize, started);
    finish(&p, &records, provenance, reused, req.quiet, req.report)
}
