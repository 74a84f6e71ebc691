//! The master on a half-duplex adapter: the direction pin is high while bytes go out and low only
//! after `flush` (the last byte has left), and an adapter that hears its own transmission has the
//! echo skipped. Fake port and pin record what happens in one shared log.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_io::{ErrorType, Read, ReadReady, Write};
use firmware::bus::master::{BusConfig, Clock, Master, MasterError};
use firmware::bus::{Protocol, Status};

#[derive(Clone, Debug, PartialEq, Eq)]
enum Event {
    PinHigh,
    PinLow,
    Write(Vec<u8>),
    Flush,
}

type Log = Rc<RefCell<Vec<Event>>>;

/// A port whose replies are queued in advance; with `echo` every written byte comes back first.
struct FakePort {
    log: Log,
    rx: VecDeque<u8>,
    replies: VecDeque<Vec<u8>>,
    echo: bool,
    pending: Vec<u8>,
}

impl ErrorType for FakePort {
    type Error = core::convert::Infallible;
}

impl Write for FakePort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.log.borrow_mut().push(Event::Write(buf.to_vec()));
        self.pending.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        self.log.borrow_mut().push(Event::Flush);
        if self.echo {
            self.rx.extend(self.pending.iter());
        }
        self.pending.clear();
        if let Some(reply) = self.replies.pop_front() {
            self.rx.extend(reply);
        }
        Ok(())
    }
}

impl Read for FakePort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = buf.len().min(self.rx.len());
        for slot in &mut buf[..n] {
            *slot = self.rx.pop_front().unwrap_or(0);
        }
        Ok(n)
    }
}

impl ReadReady for FakePort {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.rx.is_empty())
    }
}

struct FakePin(Log);

impl PinErrorType for FakePin {
    type Error = core::convert::Infallible;
}

impl OutputPin for FakePin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.0.borrow_mut().push(Event::PinLow);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.0.borrow_mut().push(Event::PinHigh);
        Ok(())
    }
}

/// A clock that moves 10 µs per look, so waits end.
struct StepClock(u64);

impl Clock for StepClock {
    fn now_us(&mut self) -> u64 {
        self.0 += 10;
        self.0
    }
}

fn status(protocol: Protocol, id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    let mut out = [0u8; 64];
    let n = protocol.encode_status(&Status { id, error, params }, &mut out).unwrap();
    out[..n].to_vec()
}

fn master(protocol: Protocol, echo: bool, replies: Vec<Vec<u8>>) -> (Master<FakePort, FakePin, StepClock>, Log) {
    let log = Log::default();
    let port = FakePort { log: log.clone(), rx: VecDeque::new(), replies: replies.into(), echo, pending: Vec::new() };
    let config = BusConfig { echo, ..BusConfig::new(protocol, 1_000_000) };
    (Master::new(port, FakePin(log.clone()), StepClock(0), config), log)
}

#[test]
fn direction_pin_brackets_the_transmission() {
    // e-manual: READ id 1 address 132 length 4, answered with position 0x000007D0.
    let reply = status(Protocol::Dxl2, 1, 0, &[0xD0, 0x07, 0, 0]);
    let (mut m, log) = master(Protocol::Dxl2, false, vec![reply]);
    let mut data = [0u8; 4];
    let answer = m.read(1, 132, &mut data).unwrap();
    assert!(answer.replied && answer.alert.is_none());
    assert_eq!(data, [0xD0, 0x07, 0, 0]);
    let log = log.borrow();
    let read = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15];
    assert_eq!(*log, [Event::PinHigh, Event::Write(read), Event::Flush, Event::PinLow]);
}

#[test]
fn echo_of_the_instruction_is_skipped() {
    // Feetech's READ and status look alike: without skipping the echo, the master would take its
    // own READ (id 1, "error" 0x02) for the reply.
    let reply = status(Protocol::Feetech, 1, 0, &[0x18, 0x05]);
    let (mut m, _) = master(Protocol::Feetech, true, vec![reply]);
    let mut data = [0u8; 2];
    m.read(1, 0x38, &mut data).unwrap();
    assert_eq!(data, [0x18, 0x05]);
}

#[test]
fn refusal_and_alert_are_told_apart() {
    // Dynamixel: error number 7 (access error) refuses; the alert bit alone does not.
    let (mut m, _) = master(Protocol::Dxl2, false, vec![status(Protocol::Dxl2, 1, 0x07, &[])]);
    let err = m.write(1, 7, &[2]).unwrap_err();
    assert!(matches!(err, MasterError::Refused { id: 1, error: 0x07, .. }), "{err:?}");
    assert_eq!(err.to_string(), "servo 1: access error");
    let (mut m, _) = master(Protocol::Dxl2, false, vec![status(Protocol::Dxl2, 1, 0x80, &[])]);
    assert_eq!(m.write(1, 116, &[0, 8, 0, 0]).unwrap().alert, Some(0x80));
}

#[test]
fn no_reply_is_retried_then_reported() {
    let (mut m, log) = master(Protocol::Feetech, false, vec![]);
    let err = m.ping(3).unwrap_err();
    assert!(matches!(err, MasterError::NoReply { id: 3, attempts: 3, corrupt: 0, .. }), "{err:?}");
    assert!(err.to_string().starts_with("servo 3: no reply to ping (3 attempts"), "{err}");
    let writes = log.borrow().iter().filter(|e| matches!(e, Event::Write(_))).count();
    assert_eq!(writes, 3);
}

#[test]
fn corrupt_reply_is_named() {
    let mut bad = status(Protocol::Feetech, 3, 0, &[]);
    let last = bad.len() - 1;
    bad[last] ^= 1;
    let (mut m, _) = master(Protocol::Feetech, false, vec![bad.clone(), bad.clone(), bad]);
    let err = m.ping(3).unwrap_err();
    assert!(matches!(err, MasterError::NoReply { corrupt: 3, .. }), "{err:?}");
    assert!(err.to_string().contains("bad checksum"), "{err}");
}

#[test]
fn a_reply_behind_a_false_header_in_noise_arrives_once_the_line_is_quiet() {
    // Noise that looks like the start of a long packet, then the real reply: the decoder must not
    // wait for the noise's announced length once the line has gone quiet.
    for (protocol, noise) in [
        (Protocol::Dxl2, vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x30, 0x00]),
        (Protocol::Feetech, vec![0xFF, 0xFF, 0x00, 0x20]),
    ] {
        let reply = [noise, status(protocol, 1, 0, &[0x18, 0x05])].concat();
        let (mut m, _) = master(protocol, false, vec![reply]);
        let mut data = [0u8; 2];
        m.read(1, 56, &mut data).unwrap_or_else(|e| panic!("{protocol:?}: {e}"));
        assert_eq!(data, [0x18, 0x05]);
        assert_eq!(m.stats().retries, 0, "{protocol:?}: answered on the first attempt");
    }
}
