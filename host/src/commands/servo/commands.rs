//! The `armctl servo` commands, on an open [`Session`]. Each writes its result lines to `out` (with
//! `json`, one line of JSON with the same content), its complaints as `error: ...` lines to `err`,
//! and returns the exit code; a failure that ends the command is an `Err` (one line, exit code 1).
//!
//! A reply whose error byte reports a hardware fault (Dynamixel alert bit, any Feetech error bit)
//! still carries its data, and the servo carried out the instruction: the result is printed, then
//! one `error: servo 3: alert: ...` line per faulty servo, and the exit code is 1 so that scripts
//! notice a servo that needs attention.

use std::io::Write;

use anyhow::{bail, Context, Result};
use firmware::bus::feetech::value::Endian;
use firmware::bus::master::{BusConfig, Clock, MasterError};
use firmware::bus::table::{Access, Encoding, Item, Model, MODELS};
use firmware::bus::{Id, Protocol, BROADCAST};
use serde_json::{json, Value};

use super::items;
use crate::runtime::servo_session::{value_error, BusFailure, Port, Servo, Session};

/// The Dynamixel error number of a write to an EEPROM item while torque is on.
const ACCESS_ERROR: u8 = 7;

/// Prints the alert lines of `session`; the exit code: 1 when there were any.
pub fn finish<P: Port, C: Clock>(session: &mut Session<P, C>, err: &mut dyn Write) -> Result<i32> {
    let alerts = session.alerts().to_vec();
    for (id, byte) in &alerts {
        let text = session.alert_text(*id, *byte);
        writeln!(err, "error: servo {id}: alert: {text}")?;
    }
    Ok(if alerts.is_empty() { 0 } else { 1 })
}

/// `00 08 00 00`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

/// Writes `value` as one line of JSON when `json`, else `text`'s lines.
pub fn print(out: &mut dyn Write, json: bool, value: Value, text: impl FnOnce() -> String) -> Result<()> {
    if json {
        writeln!(out, "{value}")?;
    } else {
        writeln!(out, "{}", text())?;
    }
    Ok(())
}

/// A servo as JSON: `{"id": 1, "model_number": 1060, "model": "XL430-W250", "firmware": 46}`.
fn servo_json(servo: &Servo) -> Value {
    json!({
        "id": servo.id,
        "model_number": servo.model_number,
        "model": servo.model.map(|m| m.name),
        "firmware": servo.firmware,
    })
}

/// Every baud rate of the protocol's models, fastest first.
pub fn protocol_bauds(protocol: Protocol) -> Vec<u32> {
    let mut bauds: Vec<u32> =
        MODELS.iter().filter(|m| m.protocol == protocol).flat_map(|m| m.bauds.iter().map(|(_, b)| *b)).collect();
    bauds.sort_unstable_by(|a, b| b.cmp(a));
    bauds.dedup();
    bauds
}

/// `scan`: pings each id at each baud; one line per servo that answers:
/// `id 1: model 1060 XL430-W250, firmware 46, 57600 baud`; with `json`, one line at the end,
/// `{"servos": [{"id": 1, "model_number": 1060, "model": "XL430-W250", "firmware": 46, "baud": 57600}]}`.
pub fn scan(
    path: &str,
    config: BusConfig,
    bauds: &[u32],
    ids: &[Id],
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let mut servos = Vec::new();
    let mut found = 0usize;
    let mut problems = 0usize;
    let mut code = 0;
    for &baud in bauds {
        let mut session = Session::open(path, BusConfig { baud, ..config })?;
        for &id in ids {
            match session.identify(id) {
                Ok(servo) => {
                    found += 1;
                    let firmware = servo.firmware.map_or_else(|| "?".to_string(), |f| f.to_string());
                    if json {
                        let mut value = servo_json(&servo);
                        value["baud"] = baud.into();
                        servos.push(value);
                    } else {
                        writeln!(out, "id {id}: model {}, firmware {firmware}, {baud} baud", servo.model_text())?;
                    }
                    if let Some(problem) = duplicate_check(&mut session, &servo) {
                        problems += 1;
                        writeln!(err, "error: {problem}")?;
                    }
                }
                Err(BusFailure(MasterError::NoReply { corrupt: 0, .. })) => {}
                // Something answered but not cleanly (two servos with one id garble each other's
                // replies; a servo that refuses a ping): say so and go on with the scan.
                Err(BusFailure(
                    e @ (MasterError::NoReply { .. } | MasterError::Refused { .. } | MasterError::BadReply { .. }),
                )) => {
                    problems += 1;
                    writeln!(err, "error: {e}")?;
                }
                Err(e) => return Err(e.into()),
            }
        }
        code = code.max(finish(&mut session, err)?);
    }
    if found == 0 && problems == 0 {
        match bauds {
            [baud] => bail!("no servos answered at {baud} baud"),
            _ => bail!("no servos answered at any of {} baud", join(bauds)),
        }
    }
    if json {
        writeln!(out, "{}", json!({ "servos": servos }))?;
    }
    Ok(if problems > 0 { 1 } else { code })
}

/// Two servos with one id answer a ping with the same bytes at the same time, which add up to one
/// valid reply; their present positions differ, so a read of it collides into a bad checksum.
pub fn duplicate_check<P: Port, C: Clock>(session: &mut Session<P, C>, servo: &Servo) -> Option<String> {
    let item = servo.model?.items.present_position;
    let mut bytes = [0u8; 4];
    match session.read(servo.id, item.address, &mut bytes[..item.len()]) {
        Err(BusFailure(e @ MasterError::NoReply { corrupt: 1.., .. })) => {
            Some(format!("{e} (two servos with id {}?)", servo.id))
        }
        _ => None,
    }
}

fn join(values: &[u32]) -> String {
    values.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
}

/// `read`: the bytes in hex on one line, then `name = value` for each known item inside them;
/// with `json`, `{"id": 1, "address": 132, "bytes": [0, 8, 0, 0], "items": {"present_position": 2048}}`.
#[allow(clippy::too_many_arguments)]
pub fn read<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    id: Id,
    address: u16,
    len: usize,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let mut bytes = vec![0u8; len];
    session.read(id, address, &mut bytes)?;
    // The model only decodes: without it (an odd ping), the bytes are still the answer.
    let decoded = match session.identify(id) {
        Ok(Servo { model: Some(model), .. }) => decode(model, items::within(model, address, len), address, &bytes)?,
        _ => Vec::new(),
    };
    print_read(out, json, id, address, &bytes, &decoded)?;
    finish(session, err)
}

/// `(name, value)` for each of `items`, decoded from `bytes` read at `address`.
fn decode(
    model: &Model,
    items: impl IntoIterator<Item = Item>,
    address: u16,
    bytes: &[u8],
) -> Result<Vec<(&'static str, i64)>> {
    let mut decoded = Vec::new();
    for item in items {
        let start = usize::from(item.address - address);
        let value = item.decode(&bytes[start..start + item.len()], model.endian).map_err(value_error)?;
        decoded.push((item.name, value));
    }
    Ok(decoded)
}

/// What `read` prints: the bytes in hex, then `name = value` for each decoded item; or JSON.
fn print_read(
    out: &mut dyn Write,
    json: bool,
    id: Id,
    address: u16,
    bytes: &[u8],
    decoded: &[(&str, i64)],
) -> Result<()> {
    if json {
        let items: serde_json::Map<String, Value> =
            decoded.iter().map(|(name, value)| (name.to_string(), Value::from(*value))).collect();
        writeln!(out, "{}", json!({ "id": id, "address": address, "bytes": bytes, "items": items }))?;
        return Ok(());
    }
    writeln!(out, "{}", hex(bytes))?;
    for (name, value) in decoded {
        writeln!(out, "{name} = {value}")?;
    }
    Ok(())
}

/// The most bytes one `read` asks for (`--len` and `--item` alike).
pub const MAX_READ: usize = 128;

/// `read --item a,b`: the named items of the servo's model, read in one transaction spanning them
/// all; prints the bytes in hex, then `name = value` for each item asked for, in the order asked.
pub fn read_items<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    id: Id,
    names: &[String],
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let servo = session.identify(id)?;
    let model = servo.known_model()?;
    let mut wanted = Vec::with_capacity(names.len());
    for name in names.iter().map(|n| n.trim()) {
        let Some(item) = items::named(model, name) else {
            let known: Vec<&str> = items::all(model).iter().map(|i| i.name).collect();
            bail!("servo {id}: model {} has no item {name:?} (it has {})", model.name, known.join(", "));
        };
        wanted.push(item);
    }
    let (Some(first), Some(end)) =
        (wanted.iter().map(|i| i.address).min(), wanted.iter().map(|i| usize::from(i.address) + i.len()).max())
    else {
        bail!("--item names no item");
    };
    let span = end - usize::from(first);
    if span > MAX_READ {
        bail!("the items lie {span} bytes apart, more than one read of {MAX_READ} bytes: read them in two calls");
    }
    let mut bytes = vec![0u8; span];
    session.read(id, first, &mut bytes)?;
    let decoded = decode(model, wanted, first, &bytes)?;
    print_read(out, json, id, first, &bytes, &decoded)?;
    finish(session, err)
}

/// The item a write of `len` bytes (or of the item's own size) at `address` means.
fn write_target(servo: &Servo, address: u16, len: Option<u8>) -> Result<Item> {
    let known = servo.model.and_then(|m| items::at(m, address));
    match (known, len) {
        (Some(item), None) => Ok(item),
        (Some(item), Some(len)) if len == item.size => Ok(item),
        // Bytes the tables do not name (or a part of an item): an unsigned number of that width.
        (_, Some(size)) => {
            Ok(Item { name: "value", address, size, access: Access::ReadWrite, encoding: Encoding::Unsigned })
        }
        (None, None) => {
            bail!("servo {}: no item of model {} starts at address {address}; give --len", servo.id, servo.model_text())
        }
    }
}

/// `write`: encodes `value` for the item at `address` and writes it:
/// `servo 1: wrote 00 08 00 00 at 116 (goal_position = 2048)`; with `json`,
/// `{"id": 1, "address": 116, "bytes": [0, 8, 0, 0], "item": "goal_position", "value": 2048}`.
#[allow(clippy::too_many_arguments)]
pub fn write<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    id: Id,
    address: u16,
    value: i64,
    len: Option<u8>,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let servo = session.identify(id)?;
    let item = write_target(&servo, address, len)?;
    if item.access == Access::Read {
        bail!("servo {id}: {} (address {address}) is read-only", item.name);
    }
    // The id and baud items change how the servo is reached: set-id checks the new id is free and
    // set-baud that the rate exists, and both confirm by pinging the servo where it now is.
    if let Some(model) = servo.model {
        let (id_item, baud_item) = (model.items.id, model.items.baud);
        let touches = |i: firmware::bus::table::Item| {
            address < i.address + u16::from(i.size) && i.address < address + u16::from(item.size)
        };
        if touches(id_item) {
            bail!("servo {id}: address {address} is the id: use armctl servo set-id");
        }
        if touches(baud_item) {
            bail!("servo {id}: address {address} is the baud rate: use armctl servo set-baud");
        }
    }
    // Dynamixel is little-endian; an unknown Feetech model is taken for an STS (little-endian).
    let endian = servo.model.map_or(Endian::Little, |m| m.endian);
    let mut bytes = [0u8; 4];
    item.encode(value, endian, &mut bytes).map_err(|_| {
        let (lo, hi) = item.range();
        anyhow::anyhow!("{value} does not fit {} ({} bytes, {lo}..={hi})", item.name, item.size)
    })?;
    let bytes = &bytes[..item.len()];
    let eeprom = servo.model.filter(|m| address < m.eeprom_end);
    match eeprom {
        Some(model) => eeprom_write(session, &servo, model, true, |s| {
            s.write(id, address, bytes).map_err(|e| explain(e, servo.model, address))?;
            Ok(())
        })?,
        None => {
            session.write(id, address, bytes).map_err(|e| explain(e, servo.model, address))?;
        }
    }
    let name = (item.name != "value").then_some(item.name);
    let value_json = json!({ "id": id, "address": address, "bytes": bytes, "item": name, "value": value });
    print(out, json, value_json, || {
        let named = name.map(|n| format!(" ({n} = {value})")).unwrap_or_default();
        format!("servo {id}: wrote {} at {address}{named}", hex(bytes))
    })?;
    finish(session, err)
}

/// Adds the way out to a Dynamixel access error on an EEPROM item.
fn explain<E: std::fmt::Debug + Send + Sync + 'static>(
    e: BusFailure<E>,
    model: Option<&Model>,
    address: u16,
) -> anyhow::Error {
    match (&e.0, model) {
        (MasterError::Refused { id, error, .. }, Some(m))
            if m.protocol == Protocol::Dxl2 && error & 0x7F == ACCESS_ERROR && address < m.eeprom_end =>
        {
            anyhow::anyhow!(
                "{e}: address {address} is EEPROM, writable only with torque off (armctl servo torque off --id {id})"
            )
        }
        _ => e.into(),
    }
}

/// Runs `write` on an EEPROM item: on Dynamixel only with torque off (checked first, so the
/// message says why instead of the servo's bare access error; torque is not switched off here,
/// as that would let the joint drop); on Feetech between unlocking and locking the EEPROM
/// (`lock` = 0, write, `lock` = 1), as LeRobot's set-up does, so the value survives a power cycle.
/// With `relock` false the caller locks again, where the servo answers after the write (new id,
/// new baud).
pub(super) fn eeprom_write<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    servo: &Servo,
    model: &Model,
    relock: bool,
    write: impl FnOnce(&mut Session<P, C>) -> Result<()>,
) -> Result<()> {
    let id = servo.id;
    if model.protocol == Protocol::Dxl2 {
        let torque = session.read_item(id, model, model.items.torque_enable)?;
        if torque != 0 {
            bail!(
                "servo {id}: torque is on; EEPROM items (below address {}) are writable only with torque off \
                 (armctl servo torque off --id {id}; the joint goes limp)",
                model.eeprom_end
            );
        }
    }
    let Some(lock) = model.items.lock else { return write(session) };
    session.write_item(id, model, lock, 0).context("cannot unlock the EEPROM")?;
    let result = write(session);
    if result.is_err() {
        // Best effort: the write's own error is the one to report.
        let _ = session.write_item(id, model, lock, 1);
    } else if relock {
        session.write_item(id, model, lock, 1).context("cannot lock the EEPROM again")?;
    }
    result
}

/// `set-id`: moves servo `id` to `new_id`, which must be free:
/// `servo 1: id is now 5 (model 1060 XL430-W250)`; with `json`, `{"id": 1, "new_id": 5, "servo": {...}}`.
pub fn set_id<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    id: Id,
    new_id: Id,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let servo = session.identify(id)?;
    let model = servo.known_model()?;
    match session.identify(new_id) {
        Ok(other) => bail!("id {new_id} is taken: servo {new_id} answered (model {})", other.model_text()),
        Err(BusFailure(MasterError::NoReply { corrupt: 0, .. })) => {}
        Err(e) => bail!("id {new_id} is not free: {e}"),
    }
    let item = model.items.id;
    let mut bytes = [0u8; 4];
    item.encode(i64::from(new_id), model.endian, &mut bytes).map_err(value_error)?;
    eeprom_write(session, &servo, model, false, |s| {
        // The status of an id write may come under either id: confirmed by a ping below instead.
        s.write_unconfirmed(id, item.address, &bytes[..item.len()])?;
        Ok(())
    })?;
    let moved = session
        .identify(new_id)
        .with_context(|| format!("servo {id}: wrote id {new_id}, but no servo answers as {new_id}"))?;
    if let Some(lock) = model.items.lock {
        session.write_item(new_id, model, lock, 1).context("cannot lock the EEPROM again")?;
    }
    print(out, json, json!({ "id": id, "new_id": new_id, "servo": servo_json(&moved) }), || {
        format!("servo {id}: id is now {new_id} (model {})", moved.model_text())
    })?;
    finish(session, err)
}

/// `set-baud`: switches servo `id` to `baud` (one the model has), then reopens the port at that
/// baud and pings it: `servo 1: baud rate is now 1000000 (baud_rate = 3)`; with `json`,
/// `{"id": 1, "baud": 1000000, "item": "baud_rate", "index": 3}`.
pub fn set_baud(
    mut session: Session,
    id: Id,
    baud: u32,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let servo = session.identify(id)?;
    let model = servo.known_model()?;
    let Some(index) = model.baud_index(baud) else {
        let bauds: Vec<u32> = model.bauds.iter().map(|(_, b)| *b).collect();
        bail!("{} has no {baud} baud; its rates are {}", model.name, join(&bauds));
    };
    let item = model.items.baud;
    let mut bytes = [0u8; 4];
    item.encode(i64::from(index), model.endian, &mut bytes).map_err(value_error)?;
    eeprom_write(&mut session, &servo, model, false, |s| {
        // The status may come at the old baud, the new one, or garbled between: confirmed by a
        // ping at the new baud instead.
        s.write_unconfirmed(id, item.address, &bytes[..item.len()])?;
        Ok(())
    })?;
    let old = session.config().baud;
    let mut session = session.reopen(baud)?;
    session.identify(id).with_context(|| {
        format!("servo {id}: wrote baud_rate = {index}, but it does not answer at {baud} baud (was {old})")
    })?;
    if let Some(lock) = model.items.lock {
        session.write_item(id, model, lock, 1).context("cannot lock the EEPROM again")?;
    }
    print(out, json, json!({ "id": id, "baud": baud, "item": item.name, "index": index }), || {
        format!("servo {id}: baud rate is now {baud} ({} = {index})", item.name)
    })?;
    finish(&mut session, err)
}

/// Which servos `torque` switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// One servo, confirmed by reading the torque item back.
    One(Id),
    /// Every servo on the bus, by a broadcast write (no replies, so unconfirmed).
    All,
}

/// `torque`: writes the torque item and reads it back: `servo 1: torque on`; with `json`,
/// `{"id": 1, "torque": true, "confirmed": true}` (`"id": "all"` for the broadcast, unconfirmed).
pub fn torque<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    target: Target,
    on: bool,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let word = if on { "on" } else { "off" };
    match target {
        Target::One(id) => {
            let servo = session.identify(id)?;
            let model = servo.known_model()?;
            let item = model.items.torque_enable;
            session.write_item(id, model, item, i64::from(on))?;
            let now = session.read_item(id, model, item)?;
            if (now != 0) != on {
                bail!("servo {id}: wrote {} = {}, but it reads back {now}", item.name, u8::from(on));
            }
            print(out, json, json!({ "id": id, "torque": on, "confirmed": true }), || {
                format!("servo {id}: torque {word}")
            })?;
        }
        Target::All => {
            let protocol = session.protocol();
            let models: Vec<&Model> = MODELS.into_iter().filter(|m| m.protocol == protocol).collect();
            let item = models[0].items.torque_enable;
            if models.iter().any(|m| m.items.torque_enable.address != item.address) {
                bail!("the {} models disagree on the torque item's address: switch them one by one", protocol.name());
            }
            session.write(BROADCAST, item.address, &[u8::from(on)])?;
            print(out, json, json!({ "id": "all", "torque": on, "confirmed": false }), || {
                format!("all servos: torque {word} (broadcast, not confirmed)")
            })?;
        }
    }
    finish(session, err)
}
