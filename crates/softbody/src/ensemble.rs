//! Running a study's fit as an MPI job (`mpirun -np N softbody fit STUDY.toml`, feature
//! `mpi`): the ranks share the recordings out and exchange their results
//! (`adjoint::study::ensemble`, where the deterministic reduction is explained); rank 0 alone
//! shows progress and writes the report. Without the feature, a run started by `mpirun` with
//! more than one process is refused (every copy would fit everything and write the same
//! report).

use adjoint::study::ensemble::Ensemble;
use std::rc::Rc;

/// The error every rank but 0 returns when the run fails: rank 0 says why, the others end
/// with a failure code and no message.
pub const QUIET_FAILURE: &str = "\u{0}failed on another rank";

/// The process count a launcher (`mpirun`, `srun`) announced in the environment, if any.
fn launched_size() -> Option<usize> {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"]
        .iter()
        .find_map(|k| std::env::var(k).ok()?.trim().parse().ok())
}

/// True when this process is one of several started by an MPI launcher.
pub fn launched() -> bool {
    launched_size().is_some_and(|n| n > 1)
}

/// The MPI world when this run is one of several processes (`None`: a run of its own).
#[cfg(feature = "mpi")]
pub fn join() -> Result<Option<Rc<dyn Ensemble>>, String> {
    if !launched() {
        return Ok(None);
    }
    let universe = mpi::initialize().ok_or("MPI was already initialised in this process")?;
    let world = universe.world();
    {
        use mpi::traits::Communicator;
        if world.rank() != 0 {
            crate::output::SILENT.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
    Ok(Some(Rc::new(World {
        world,
        _universe: universe,
    })))
}

/// Without the `mpi` feature: refuses a run started as several processes.
#[cfg(not(feature = "mpi"))]
pub fn join() -> Result<Option<Rc<dyn Ensemble>>, String> {
    if launched() {
        return Err("this softbody was built without MPI: started by mpirun with several processes, each would fit everything and write the same report; build it with `cargo build --release -p softbody --features mpi`".into());
    }
    Ok(None)
}

/// The MPI world (finalised when dropped).
#[cfg(feature = "mpi")]
struct World {
    world: mpi::topology::SimpleCommunicator,
    // dropped last: MPI_Finalize
    _universe: mpi::environment::Universe,
}

#[cfg(feature = "mpi")]
impl Ensemble for World {
    fn rank(&self) -> usize {
        use mpi::traits::Communicator;
        self.world.rank() as usize
    }
    fn size(&self) -> usize {
        use mpi::traits::Communicator;
        self.world.size() as usize
    }
    fn all_gather(&self, mine: &[u8]) -> Vec<Vec<u8>> {
        use mpi::datatype::PartitionMut;
        use mpi::traits::CommunicatorCollectives;
        use mpi::Count;
        let size = self.size();
        let n = Count::try_from(mine.len()).expect("a rank's results fit in an MPI count");
        let mut counts = vec![0 as Count; size];
        self.world.all_gather_into(&n, &mut counts[..]);
        let displs: Vec<Count> = counts
            .iter()
            .scan(0 as Count, |at, &c| {
                let d = *at;
                *at += c;
                Some(d)
            })
            .collect();
        let total: usize = counts.iter().map(|&c| c as usize).sum();
        let mut buf = vec![0u8; total];
        {
            let mut part = PartitionMut::new(&mut buf[..], &counts[..], &displs[..]);
            self.world.all_gather_varcount_into(mine, &mut part);
        }
        counts
            .iter()
            .zip(&displs)
            .map(|(&c, &d)| buf[d as usize..(d + c) as usize].to_vec())
            .collect()
    }
}
