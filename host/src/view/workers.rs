//! The threads that serve connections: one per open connection, as many as the caps allow, kept
//! and reused rather than started anew for every request. A flood of short requests then costs
//! no thread creation (each of which maps and unmaps a stack under the process's memory lock,
//! which the control loop's threads wait on too), and a slow client still holds only its own
//! thread: [`Workers::run`] hands each task to a thread reserved for it, never queues it behind
//! another.
//!
//! The workers run nicer than the rest of the process ([`NICENESS`]), so that under load the
//! firmware core's control loop (in this process for `--sim` and `--bus`) and the arm loop get the
//! processor first.

use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};

/// A connection's work.
pub type Task = Box<dyn FnOnce() + Send>;

/// How much nicer than the rest of the process the workers are. A stop is read on one too, and
/// still in a millisecond or so: it is a few hundred bytes.
const NICENESS: i32 = 10;

#[derive(Default)]
struct Count {
    /// Workers waiting for a task and not reserved for one.
    idle: usize,
    /// Workers started.
    started: usize,
}

/// A pool of at most `max` threads, started as needed.
pub struct Workers {
    tasks: Sender<Task>,
    inbox: Arc<Mutex<Receiver<Task>>>,
    count: Arc<Mutex<Count>>,
    max: usize,
    stack: usize,
}

impl Workers {
    /// A pool of up to `max` threads of `stack` bytes each; none is started yet.
    pub fn new(max: usize, stack: usize) -> Self {
        let (tasks, inbox) = mpsc::channel();
        Self { tasks, inbox: Arc::new(Mutex::new(inbox)), count: Arc::default(), max, stack }
    }

    /// Runs `task` on a thread of its own: an idle worker, or a new one. Gives the task back when
    /// all `max` are busy or no thread can be had.
    pub fn run(&self, task: Task) -> Result<(), Task> {
        {
            let mut count = self.count.lock().unwrap_or_else(|e| e.into_inner());
            if count.idle > 0 {
                count.idle -= 1;
            } else if count.started < self.max && self.start().is_ok() {
                count.started += 1;
            } else {
                return Err(task);
            }
        }
        // A worker is reserved for it: idle in recv, or about to be.
        self.tasks.send(task).map_err(|e| e.0)
    }

    fn start(&self) -> std::io::Result<()> {
        let (inbox, count) = (self.inbox.clone(), self.count.clone());
        std::thread::Builder::new().name("view-conn".into()).stack_size(self.stack).spawn(move || {
            lower_priority();
            loop {
                let task = inbox.lock().unwrap_or_else(|e| e.into_inner()).recv();
                let Ok(task) = task else { return };
                task();
                count.lock().unwrap_or_else(|e| e.into_inner()).idle += 1;
            }
        })?;
        Ok(())
    }

    /// Threads started so far.
    pub fn started(&self) -> usize {
        self.count.lock().unwrap_or_else(|e| e.into_inner()).started
    }
}

/// Makes the calling thread nicer by [`NICENESS`] (Linux schedules each thread by its own nice
/// value, and lowering one's own priority needs no privilege). Best effort.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: gettid, getpriority and setpriority act on the calling thread only.
    unsafe {
        let tid = libc::gettid() as libc::id_t;
        let now = libc::getpriority(libc::PRIO_PROCESS, tid);
        libc::setpriority(libc::PRIO_PROCESS, tid, (now + NICENESS).min(19));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A task that holds its thread until `release` sends (or is dropped).
    fn holding(release: &Arc<Mutex<Receiver<()>>>) -> Task {
        let release = release.clone();
        Box::new(move || {
            let _ = release.lock().unwrap().recv();
        })
    }

    /// A task that says when it ran.
    fn signalling(ran: &Sender<()>) -> Task {
        let ran = ran.clone();
        Box::new(move || ran.send(()).unwrap())
    }

    #[test]
    fn a_busy_worker_never_delays_a_task_and_idle_ones_are_reused() {
        let pool = Workers::new(2, 64 << 10);
        let (release, held) = mpsc::channel::<()>();
        let held = Arc::new(Mutex::new(held));
        let (ran, said) = mpsc::channel::<()>();
        assert!(pool.run(holding(&held)).is_ok());
        // Not behind the held one: a thread of its own.
        assert!(pool.run(signalling(&ran)).is_ok());
        said.recv_timeout(Duration::from_secs(5)).expect("the second task ran while the first held its thread");
        // Two busy: a third is given back, not queued.
        std::thread::sleep(Duration::from_millis(50));
        assert!(pool.run(holding(&held)).is_ok(), "the second thread is idle again");
        assert!(pool.run(signalling(&ran)).is_err(), "both threads busy: given back");
        release.send(()).unwrap();
        release.send(()).unwrap();
        // A hundred short tasks reuse the two threads.
        for _ in 0..100 {
            while pool.run(signalling(&ran)).is_err() {
                std::thread::sleep(Duration::from_millis(1));
            }
            said.recv_timeout(Duration::from_secs(5)).expect("a short task ran");
        }
        assert_eq!(pool.started(), 2);
    }
}
