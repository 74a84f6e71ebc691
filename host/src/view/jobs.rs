//! The requests waiting for the arm loop: stop first, the rest bounded, none run late.
//!
//! - A stop or torque off ([`urgent`]) goes ahead of every queued job: it waits at most for the
//!   job or status poll under way (a few milliseconds of link time).
//! - At most [`CAPACITY`] other jobs wait; one more is answered 503 at once.
//! - A job not started within [`START_TIME`] is dropped, not run later: its caller was answered
//!   503 and may have sent something else since.
//!
//! The arm loop waits on the queue between polls ([`JobQueue::wait`]), so a job is taken as soon
//! as it comes, not at the next poll.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::api::{ApiError, Request};

/// Jobs that may wait besides urgent ones.
pub const CAPACITY: usize = 8;
/// Urgent jobs that may wait (each is a stop or torque off: more add nothing).
const URGENT_CAPACITY: usize = 32;
/// How long a job may wait to be started.
pub const START_TIME: Duration = Duration::from_secs(5);
/// How long a started job may take to answer (link requests time out well within it).
const RUN_TIME: Duration = Duration::from_secs(30);

/// A job's fate, agreed on by the caller and the arm loop.
const WAITING: u8 = 0;
const STARTED: u8 = 1;
const ABANDONED: u8 = 2;

/// The answer to a job.
pub type Answer = Result<Value, ApiError>;

/// A request for the arm loop, with where to answer it.
pub struct Job {
    /// What to do.
    pub request: Request,
    reply: Sender<Answer>,
    fate: Arc<AtomicU8>,
}

impl Job {
    /// Sends the answer (the caller may have gone: then nobody hears it).
    pub fn answer(self, answer: Answer) {
        let _ = self.reply.send(answer);
    }

    /// The request, and where its answer goes: the request is moved out, not copied (a file to
    /// play is megabytes).
    pub fn split(self) -> (Request, Reply) {
        (self.request, Reply(self.reply))
    }
}

/// Where a job's answer goes.
pub struct Reply(Sender<Answer>);

impl Reply {
    /// Sends the answer (the caller may have gone: then nobody hears it).
    pub fn send(self, answer: Answer) {
        let _ = self.0.send(answer);
    }
}

/// Whether a request goes ahead of the others.
pub fn urgent(request: &Request) -> bool {
    matches!(request, Request::Stop | Request::Torque(false))
}

#[derive(Default)]
struct Queues {
    urgent: VecDeque<Job>,
    normal: VecDeque<Job>,
    closed: bool,
}

/// The queue between the server's threads and the arm loop.
#[derive(Default)]
pub struct JobQueue {
    queues: Mutex<Queues>,
    arrived: Condvar,
}

impl JobQueue {
    fn lock(&self) -> std::sync::MutexGuard<'_, Queues> {
        self.queues.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queues `request` and waits for its answer (on the caller's thread).
    pub fn submit(&self, request: Request) -> Answer {
        self.enqueue(request)?.wait()
    }

    /// Queues `request` without waiting: a rig's stop is queued on every arm before any answer is
    /// awaited, so no arm's stop waits behind another arm's.
    pub fn enqueue(&self, request: Request) -> Result<Pending, ApiError> {
        let (reply, answer) = mpsc::channel();
        let fate = Arc::new(AtomicU8::new(WAITING));
        {
            let mut q = self.lock();
            if q.closed {
                return Err(closed());
            }
            let (queue, capacity) = match urgent(&request) {
                true => (&mut q.urgent, URGENT_CAPACITY),
                false => (&mut q.normal, CAPACITY),
            };
            if queue.len() >= capacity {
                return Err(ApiError::new(503, format!("{capacity} requests are waiting already: try again")));
            }
            queue.push_back(Job { request, reply, fate: fate.clone() });
        }
        self.arrived.notify_all();
        Ok(Pending { answer, fate })
    }

    /// The next job to run, urgent ones first; jobs their callers gave up on are dropped.
    pub fn next(&self) -> Option<Job> {
        let mut q = self.lock();
        loop {
            let job = q.urgent.pop_front().or_else(|| q.normal.pop_front())?;
            if job.fate.compare_exchange(WAITING, STARTED, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
                return Some(job);
            }
        }
    }

    /// Waits until `until` or until a job arrives, whichever is first.
    pub fn wait(&self, until: Instant) {
        let q = self.lock();
        let left = until.saturating_duration_since(Instant::now());
        if q.urgent.is_empty() && q.normal.is_empty() && !left.is_zero() {
            let _ = self.arrived.wait_timeout_while(q, left, |q| q.urgent.is_empty() && q.normal.is_empty());
        }
    }

    /// Refuses every new job, and answers the waiting ones 503 (the view is closing).
    pub fn close(&self) {
        let mut q = self.lock();
        q.closed = true;
        let Queues { urgent, normal, .. } = &mut *q;
        for job in urgent.drain(..).chain(normal.drain(..)) {
            job.answer(Err(closed()));
        }
    }
}

/// A queued job's answer, to wait for.
pub struct Pending {
    answer: mpsc::Receiver<Answer>,
    fate: Arc<AtomicU8>,
}

impl Pending {
    /// Waits for the answer: a job not started within [`START_TIME`] is dropped, not run later.
    pub fn wait(self) -> Answer {
        let Self { answer, fate } = self;
        match answer.recv_timeout(START_TIME) {
            Ok(answer) => return answer,
            Err(mpsc::RecvTimeoutError::Disconnected) => return Err(closed()),
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if fate.compare_exchange(WAITING, ABANDONED, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            return Err(ApiError::new(
                503,
                format!("the arm loop did not take the request within {} s: dropped, not run", START_TIME.as_secs()),
            ));
        }
        // Started: it will answer (or the loop has ended).
        answer.recv_timeout(RUN_TIME).unwrap_or_else(|_| Err(closed()))
    }
}

fn closed() -> ApiError {
    ApiError::new(503, "the view is closing: the arm is being stopped")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joints() -> Request {
        Request::Joints { q: vec![0.0], speed: None }
    }

    /// Submits on a thread of its own, as a connection does; returns its answer's receiver.
    fn submit(queue: &Arc<JobQueue>, request: Request) -> std::thread::JoinHandle<Answer> {
        let queued = |q: &Queues| q.urgent.len() + q.normal.len();
        let before = queued(&queue.lock());
        let handle = {
            let queue = queue.clone();
            std::thread::spawn(move || queue.submit(request))
        };
        // Until it is queued.
        let started = Instant::now();
        while started.elapsed() < Duration::from_secs(2) {
            let q = queue.lock();
            if queued(&q) > before || handle.is_finished() {
                break;
            }
            drop(q);
            std::thread::sleep(Duration::from_millis(1));
        }
        handle
    }

    #[test]
    fn stop_and_torque_off_go_ahead_of_queued_jobs() {
        let queue = Arc::new(JobQueue::default());
        let first = submit(&queue, joints());
        let second = submit(&queue, Request::Torque(true));
        let stop = submit(&queue, Request::Stop);
        let off = submit(&queue, Request::Torque(false));
        let order: Vec<Request> = std::iter::from_fn(|| queue.next())
            .map(|job| {
                let request = job.request.clone();
                job.answer(Ok(Value::Null));
                request
            })
            .collect();
        assert_eq!(order, vec![Request::Stop, Request::Torque(false), joints(), Request::Torque(true)]);
        for h in [first, second, stop, off] {
            assert_eq!(h.join().unwrap(), Ok(Value::Null));
        }
    }

    #[test]
    fn a_full_queue_answers_503_at_once_and_a_stop_still_gets_in() {
        let queue = Arc::new(JobQueue::default());
        let waiting: Vec<_> = (0..CAPACITY).map(|_| submit(&queue, joints())).collect();
        let refused_at = Instant::now();
        let refused = queue.submit(joints()).unwrap_err();
        assert_eq!(refused.status, 503);
        assert!(refused_at.elapsed() < Duration::from_secs(1), "refused at once");
        let stop = submit(&queue, Request::Stop);
        assert_eq!(queue.next().map(|j| j.request.clone()), Some(Request::Stop));
        queue.close();
        for h in waiting {
            assert_eq!(h.join().unwrap().unwrap_err().status, 503);
        }
        assert_eq!(stop.join().unwrap().unwrap_err().status, 503, "taken, then the loop ended without an answer");
        assert_eq!(queue.submit(Request::Stop).unwrap_err().status, 503, "closed");
    }

    #[test]
    fn a_job_its_caller_gave_up_on_is_dropped_not_run() {
        let queue = Arc::new(JobQueue::default());
        let caller = submit(&queue, joints());
        // The arm loop is busy past the caller's patience.
        let answer = caller.join().unwrap().unwrap_err();
        assert_eq!(answer.status, 503);
        assert!(answer.message.contains("dropped, not run"), "{answer:?}");
        assert!(queue.next().is_none(), "the abandoned job is not handed to the loop");
    }

    #[test]
    fn the_loop_wakes_when_a_job_arrives() {
        let queue = Arc::new(JobQueue::default());
        let waiter = {
            let queue = queue.clone();
            std::thread::spawn(move || {
                let started = Instant::now();
                queue.wait(started + Duration::from_secs(10));
                started.elapsed()
            })
        };
        std::thread::sleep(Duration::from_millis(50));
        let stop = submit(&queue, Request::Stop);
        assert!(waiter.join().unwrap() < Duration::from_secs(5));
        queue.next().unwrap().answer(Ok(Value::Null));
        assert!(stop.join().unwrap().is_ok());
    }
}
