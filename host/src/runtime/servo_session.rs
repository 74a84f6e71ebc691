//! An open servo bus: the firmware's master on a serial port, with the servo identification and
//! the alert bookkeeping every command shares.

use std::time::Duration;

use firmware::bus::master::{Answer, BusConfig, Clock, Master, MasterError, NoDirectionPin, PingInfo, Replies};
use firmware::bus::table::{Item, Model, ValueError, MODELS};
use firmware::bus::{Id, Protocol};

use crate::link::serial::{OpenError, SerialTransport, StdClock, TransportError};

pub use crate::link::serial::{Bus, Port};

/// A failed transaction as an error value for `anyhow`; its text is the master's one line
/// ("servo 3: no reply to read (3 attempts, 10.150 ms each)").
#[derive(Debug, Clone)]
pub struct BusFailure<E = TransportError>(pub MasterError<E>);

impl<E: std::fmt::Debug> std::fmt::Display for BusFailure<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl<E: std::fmt::Debug> std::error::Error for BusFailure<E> {}

impl<E> From<MasterError<E>> for BusFailure<E> {
    fn from(e: MasterError<E>) -> Self {
        Self(e)
    }
}

/// Servos that did not answer a sync read in all its attempts: a loose cable, or a reply late on
/// a busy PC; a caller sampling over time may take it as one missed sample.
#[derive(Debug, Clone)]
pub struct NoAnswer {
    /// The servos whose data did not arrive.
    pub missing: Vec<Id>,
    /// The item read.
    pub item: &'static str,
    /// The attempts made.
    pub attempts: u8,
}

impl std::fmt::Display for NoAnswer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ids: Vec<String> = self.missing.iter().map(Id::to_string).collect();
        write!(f, "servo {} did not answer a sync read of {} ({} attempts)", ids.join(", "), self.item, self.attempts)
    }
}

impl std::error::Error for NoAnswer {}

/// What a servo says about itself.
#[derive(Clone, Copy, Debug)]
pub struct Servo {
    /// Its id.
    pub id: Id,
    /// Its model number (from the ping on Dynamixel, the model item on Feetech).
    pub model_number: u16,
    /// The model, when the firmware's tables know the number.
    pub model: Option<&'static Model>,
    /// Its firmware version (from the ping on Dynamixel, the firmware item on Feetech), when known.
    pub firmware: Option<u8>,
}

impl Servo {
    /// `1060 XL430-W250`, or `1234 (unknown model)`.
    pub fn model_text(&self) -> String {
        match self.model {
            Some(m) => format!("{} {}", self.model_number, m.name),
            None => format!("{} (unknown model)", self.model_number),
        }
    }

    /// The model, or an error naming the number when the tables do not know it.
    pub fn known_model(&self) -> anyhow::Result<&'static Model> {
        self.model.ok_or_else(|| {
            anyhow::anyhow!("servo {}: model number {} is not in armctl's tables", self.id, self.model_number)
        })
    }
}

/// An open bus on one port.
#[derive(Debug)]
pub struct Session<P = SerialTransport, C = StdClock> {
    path: String,
    master: Bus<P, C>,
    /// Hardware-fault bytes reported in replies, per servo, in order of first report.
    alerts: Vec<(Id, u8)>,
}

impl Session {
    /// Opens `path` at `config.baud` and puts the master on it.
    pub fn open(path: &str, config: BusConfig) -> Result<Self, OpenError> {
        let port = SerialTransport::open(path, config.baud)?;
        Ok(Self::new(path, port, StdClock::new(), config))
    }

    /// The same port at another baud rate. The old port is closed first: ports are opened
    /// exclusively, so both cannot be open at once.
    pub fn reopen(self, baud: u32) -> Result<Self, OpenError> {
        let config = BusConfig { baud, ..*self.master.config() };
        let Self { path, master, alerts } = self;
        drop(master);
        let mut session = Self::open(&path, config)?;
        session.alerts = alerts;
        Ok(session)
    }
}

impl<P: Port, C: Clock> Session<P, C> {
    /// A session on a port opened elsewhere (the simulator's line in tests); `name` stands for
    /// the path in messages.
    pub fn new(name: &str, port: P, clock: C, config: BusConfig) -> Self {
        Self { path: name.to_string(), master: Master::new(port, NoDirectionPin, clock, config), alerts: Vec::new() }
    }

    /// The port's path.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The bus configuration.
    pub fn config(&self) -> BusConfig {
        *self.master.config()
    }

    /// Changes the bus configuration (reply margin and idle gap once the adapter is timed).
    pub fn set_config(&mut self, config: BusConfig) {
        self.master.set_config(config);
    }

    /// The master itself, for what the session does not wrap (timing the bus).
    pub fn master_mut(&mut self) -> &mut Bus<P, C> {
        &mut self.master
    }

    /// The protocol spoken.
    pub fn protocol(&self) -> Protocol {
        self.master.config().protocol
    }

    fn note(&mut self, id: Id, answer_alert: Option<u8>) {
        if let Some(byte) = answer_alert {
            if !self.alerts.iter().any(|(i, _)| *i == id) {
                self.alerts.push((id, byte));
            }
        }
    }

    /// Pings one servo.
    pub fn ping(&mut self, id: Id) -> Result<PingInfo, BusFailure<P::Fault>> {
        let info = self.master.ping(id)?;
        self.note(id, info.alert);
        Ok(info)
    }

    /// Reads `out.len()` bytes from `address`.
    pub fn read(&mut self, id: Id, address: u16, out: &mut [u8]) -> Result<Answer, BusFailure<P::Fault>> {
        let answer = self.master.read(id, address, out)?;
        self.note(id, answer.alert);
        Ok(answer)
    }

    /// Writes `data` at `address` and waits for the status.
    pub fn write(&mut self, id: Id, address: u16, data: &[u8]) -> Result<Answer, BusFailure<P::Fault>> {
        let answer = self.master.write(id, address, data)?;
        self.note(id, answer.alert);
        Ok(answer)
    }

    /// Writes without waiting for a status: for the id and baud items, whose reply may come under
    /// the new id or at the new baud (or at neither). The caller confirms with a ping. The time
    /// of one reply is let pass, so that a late status is stale input for the next transaction,
    /// which drops it.
    pub fn write_unconfirmed(&mut self, id: Id, address: u16, data: &[u8]) -> Result<(), BusFailure<P::Fault>> {
        let config = self.config();
        self.master.set_config(BusConfig { replies: Replies::PingOnly, ..config });
        let sent = self.master.write(id, address, data);
        self.master.set_config(config);
        sent?;
        std::thread::sleep(Duration::from_micros(self.master.reply_timeout_us(1, 0)));
        Ok(())
    }

    /// Reads one item's value.
    pub fn read_item(&mut self, id: Id, model: &Model, item: Item) -> anyhow::Result<i64> {
        let mut bytes = [0u8; 4];
        let bytes = &mut bytes[..item.len()];
        self.read(id, item.address, bytes)?;
        item.decode(bytes, model.endian).map_err(value_error)
    }

    /// Writes one item's value (refused when it does not fit the item).
    pub fn write_item(&mut self, id: Id, model: &Model, item: Item, value: i64) -> anyhow::Result<()> {
        let mut bytes = [0u8; 4];
        item.encode(value, model.endian, &mut bytes).map_err(value_error)?;
        self.write(id, item.address, &bytes[..item.len()])?;
        Ok(())
    }

    /// Reads one item of every servo in `ids` with one sync read (the master retries the servos
    /// that did not answer); fails naming the servos that never did. A group reply's fault bits
    /// are not booked as alerts (the report does not carry the error byte).
    pub fn sync_read_item(&mut self, ids: &[Id], model: &Model, item: Item) -> anyhow::Result<Vec<i64>> {
        let len = item.len();
        let mut bytes = vec![0u8; ids.len() * len];
        let report = self.master.sync_read(item.address, len as u16, ids, &mut bytes).map_err(BusFailure)?;
        let missing: Vec<Id> = report.missing(ids).collect();
        if !missing.is_empty() {
            return Err(NoAnswer { missing, item: item.name, attempts: report.attempts }.into());
        }
        bytes.chunks(len).map(|b| item.decode(b, model.endian).map_err(value_error)).collect()
    }

    /// Pings `id` and finds its model and firmware version.
    pub fn identify(&mut self, id: Id) -> Result<Servo, BusFailure<P::Fault>> {
        let info = self.ping(id)?;
        match (info.model, self.protocol()) {
            (Some(number), protocol) => Ok(Servo {
                id,
                model_number: number,
                model: Model::by_number(protocol, number),
                firmware: info.firmware,
            }),
            // A Feetech ping carries nothing: read the model item, in the byte order of each model
            // the tables know until one matches.
            (None, protocol) => {
                let mut found = None;
                let mut first = None;
                for model in MODELS.into_iter().filter(|m| m.protocol == protocol) {
                    let item = model.items.model_number;
                    let mut bytes = [0u8; 4];
                    let bytes = &mut bytes[..item.len()];
                    self.read(id, item.address, bytes)?;
                    let number = item.decode(bytes, model.endian).ok().and_then(|n| u16::try_from(n).ok());
                    first = first.or(number);
                    if number == Some(model.number) {
                        found = Some(model);
                        break;
                    }
                }
                let firmware = match found {
                    Some(model) => {
                        let item = model.items.firmware;
                        let mut byte = [0u8; 1];
                        // A firmware item wider than one byte is not shown rather than misread.
                        (item.len() == 1 && self.read(id, item.address, &mut byte).is_ok()).then_some(byte[0])
                    }
                    None => None,
                };
                Ok(Servo { id, model_number: found.map_or(first.unwrap_or(0), |m| m.number), model: found, firmware })
            }
        }
    }

    /// Hardware faults reported so far, one per servo: (id, error byte).
    pub fn alerts(&self) -> &[(Id, u8)] {
        &self.alerts
    }

    /// The one-line description of servo `id`'s fault byte: on Dynamixel the bits of its hardware
    /// error status (read now), on Feetech the error byte's bits.
    pub fn alert_text(&mut self, id: Id, error: u8) -> String {
        let protocol = self.protocol();
        let generic =
            protocol.describe_error(error).map_or_else(|| format!("error byte {error:#04x}"), |t| t.to_string());
        if protocol == Protocol::Feetech {
            return if error.count_ones() > 1 { format!("{generic} (error bits {error:#04x})") } else { generic };
        }
        // Dynamixel's alert bit only says "see the hardware error status": read it.
        let status = self
            .master
            .ping(id)
            .ok()
            .and_then(|info| info.model)
            .and_then(|number| Model::by_number(protocol, number))
            .and_then(|model| model.items.hardware_error.map(|item| (model, item)))
            .and_then(|(model, item)| {
                let mut bytes = [0u8; 4];
                let bytes = &mut bytes[..item.len()];
                self.master.read(id, item.address, bytes).ok()?;
                item.decode(bytes, model.endian).ok()
            });
        match status {
            Some(bits) => format!("hardware error status {bits:#04x} ({})", hardware_errors(bits)),
            None => generic,
        }
    }
}

/// A table value error for `anyhow` (the firmware's error is `no_std`, without `std::error::Error`).
pub fn value_error(e: ValueError) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

/// The names of the hardware fault bits set in `bits`, lowest bit first: on Dynamixel the X-series
/// hardware error status (e-manual, address 70), on Feetech the status error byte (the
/// firmware's [`firmware::bus::feetech::StatusError`] bits).
pub fn hardware_error_names(protocol: Protocol, bits: u8) -> Vec<&'static str> {
    use firmware::bus::feetech::StatusError;
    const DYNAMIXEL: [(u8, &str); 5] = [
        (0x01, "input voltage"),
        (0x04, "overheating"),
        (0x08, "motor encoder"),
        (0x10, "electrical shock"),
        (0x20, "overload"),
    ];
    const FEETECH: [(u8, &str); 5] = [
        (StatusError::VOLTAGE, "input voltage"),
        (StatusError::SENSOR, "angle sensor"),
        (StatusError::OVERHEAT, "overheating"),
        (StatusError::OVERCURRENT, "overcurrent"),
        (StatusError::OVERLOAD, "overload"),
    ];
    let names: &[(u8, &str)] = match protocol {
        Protocol::Dxl2 => &DYNAMIXEL,
        Protocol::Feetech => &FEETECH,
    };
    names.iter().filter(|(bit, _)| bits & bit != 0).map(|(_, name)| *name).collect()
}

/// The X-series hardware error status bits in words.
fn hardware_errors(bits: i64) -> String {
    let names = hardware_error_names(Protocol::Dxl2, bits as u8);
    if names.is_empty() {
        "no fault bit set".to_string()
    } else {
        names.join(", ")
    }
}
