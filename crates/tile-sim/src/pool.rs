//! A tiny persistent worker pool for `VecEnv::step`.
//!
//! `std::thread::scope` joins every spawned thread, so on a shared machine one step call waited
//! for a thread that had not even been scheduled yet (measured: 2 threads slower than 1). Here
//! the caller runs the job too and only waits for workers that actually *started* it; a worker
//! that wakes after the caller finished finds no job and goes back to sleep. The job itself pulls
//! work blocks from a shared queue, so late workers simply take fewer blocks.

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

/// Lifetime-erased pointer to the current job (only dereferenced while the job's owner is
/// blocked in [`Pool::run`], which outlives every call through it).
#[derive(Clone, Copy)]
struct JobPtr(*const (dyn Fn() + Sync));
// SAFETY: the pointee is `Sync` and is only used while `Pool::run` keeps it alive (see above).
unsafe impl Send for JobPtr {}

struct State {
    generation: u64,
    job: Option<JobPtr>,
    active: usize,
    shutdown: bool,
}

struct Shared {
    state: Mutex<State>,
    wake: Condvar,
    done: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

pub(crate) struct Pool {
    shared: Arc<Shared>,
    handles: Vec<JoinHandle<()>>,
}

impl Pool {
    /// A pool with `workers` extra threads (0 = the caller does everything).
    pub(crate) fn new(workers: usize) -> Pool {
        let shared = Arc::new(Shared {
            state: Mutex::new(State { generation: 0, job: None, active: 0, shutdown: false }),
            wake: Condvar::new(),
            done: Condvar::new(),
        });
        let handles = (0..workers)
            .map(|_| {
                let sh = Arc::clone(&shared);
                std::thread::spawn(move || worker(&sh))
            })
            .collect();
        Pool { shared, handles }
    }

    pub(crate) fn workers(&self) -> usize {
        self.handles.len()
    }

    /// Run `job` on the caller and on every worker that picks it up before the caller is done;
    /// returns when no worker is inside `job` any more.
    pub(crate) fn run(&self, job: &(dyn Fn() + Sync)) {
        if self.handles.is_empty() {
            job();
            return;
        }
        // SAFETY: erase the lifetime; the pointer is withdrawn (under the lock) and every worker
        // that took it has left `job` before this function returns.
        let ptr: *const (dyn Fn() + Sync + 'static) =
            unsafe { std::mem::transmute(job as *const (dyn Fn() + Sync)) };
        {
            let mut st = self.shared.lock();
            st.generation = st.generation.wrapping_add(1);
            st.job = Some(JobPtr(ptr));
        }
        self.shared.wake.notify_all();
        job();
        let mut st = self.shared.lock();
        st.job = None;
        while st.active > 0 {
            st = self.shared.done.wait(st).unwrap_or_else(|e| e.into_inner());
        }
    }
}

fn worker(sh: &Shared) {
    let mut seen = 0u64;
    loop {
        let job = {
            let mut st = sh.lock();
            loop {
                if st.shutdown {
                    return;
                }
                if st.generation != seen {
                    seen = st.generation;
                    if let Some(j) = st.job {
                        st.active += 1;
                        break j;
                    }
                }
                st = sh.wake.wait(st).unwrap_or_else(|e| e.into_inner());
            }
        };
        // SAFETY: `active` was raised under the lock while the job was published, so the owner
        // waits in `Pool::run` until this call returns.
        unsafe { (*job.0)() };
        let mut st = sh.lock();
        st.active -= 1;
        if st.active == 0 {
            sh.done.notify_all();
        }
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        self.shared.lock().shutdown = true;
        self.shared.wake.notify_all();
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}
