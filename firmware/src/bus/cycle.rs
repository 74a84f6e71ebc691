//! One control cycle on the bus: the goals of every joint out in one sync write, the present
//! positions of every joint back through one sync read. That is the least traffic the protocols
//! allow for the job ([`super::timing::cycle_bytes`] counts it), and the controller's tick runs it.

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};

use super::instruction::RecordWriter;
use super::master::{Clock, GroupReport, Master, MasterError, PortError, MAX_GROUP};
use super::table::{Item, Model};
use super::Id;

/// The servos of an arm, one model, in joint order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoGroup<const N: usize> {
    /// Their model (the items and byte order used).
    pub model: &'static Model,
    /// Their ids, joint by joint.
    pub ids: [Id; N],
    /// How many of them are on the bus: the first `servos`. The joints after them pad a firmware
    /// built for more joints than its arm has (fixed joints, see [`kinematics::JointKind::Fixed`]):
    /// they are neither written nor read, and a read reports them answered with their values as
    /// they were.
    pub servos: usize,
}

impl<const N: usize> ServoGroup<N> {
    /// A group of `N` servos, all on the bus.
    pub const fn new(model: &'static Model, ids: [Id; N]) -> Self {
        Self { model, ids, servos: N }
    }

    /// The servos on the bus: at most `N`.
    fn on_bus(&self) -> usize {
        self.servos.min(N)
    }

    /// Sends `goals` (ticks, joint by joint) in one sync write, then reads every present position
    /// in one sync read into `positions`. Positions of servos that did not answer are left as they
    /// were; the report says which.
    pub fn cycle<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        goals: &[i32; N],
        positions: &mut [i32; N],
    ) -> Result<GroupReport, PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        self.write_all(master, self.model.items.goal_position, goals)?;
        self.read_all(master, self.model.items.present_position, positions)
    }

    /// Writes one item of every servo in one sync write (`values` joint by joint).
    pub fn write_all<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        item: Item,
        values: &[i32; N],
    ) -> Result<(), PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        self.write_with(master, item, values, None)
    }

    /// As [`ServoGroup::write_all`], with one more servo's value in the same sync write (`extra`:
    /// its id and value): an actuator outside the joints, such as a gripper, costs one record.
    pub fn write_with<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        item: Item,
        values: &[i32; N],
        extra: Option<(Id, i32)>,
    ) -> Result<(), PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let mut ids = [0 as Id; MAX_GROUP];
        let mut all = [0i32; MAX_GROUP];
        let on_bus = self.on_bus();
        let pairs = self.ids.iter().copied().zip(values.iter().copied()).take(on_bus).chain(extra);
        let mut count = 0;
        for ((slot, value), (id, v)) in ids.iter_mut().zip(all.iter_mut()).zip(pairs) {
            (*slot, *value) = (id, v);
            count += 1;
        }
        if count < on_bus + usize::from(extra.is_some()) {
            return Err(MasterError::BadRequest { reason: "more servos than MAX_GROUP (32)" });
        }
        let (ids, all) = (ids.get(..count).unwrap_or_default(), all.get(..count).unwrap_or_default());
        write_values(master, self.model, item, ids, all)
    }

    /// Reads one item of every servo in one sync read into `values` (joint by joint).
    pub fn read_all<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        item: Item,
        values: &mut [i32; N],
    ) -> Result<GroupReport, PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        self.read_with(master, item, values, None)
    }

    /// As [`ServoGroup::read_all`], with one more servo in the same sync read (`extra`: its id and
    /// where its value goes); the report's bit `N` is that servo's, and it counts `N` servos (plus
    /// the extra one), the padding joints answered.
    pub fn read_with<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        item: Item,
        values: &mut [i32; N],
        extra: Option<(Id, &mut i32)>,
    ) -> Result<GroupReport, PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let on_bus = self.on_bus();
        let count = on_bus + usize::from(extra.is_some());
        if N + usize::from(extra.is_some()) > MAX_GROUP {
            return Err(MasterError::BadRequest { reason: "more servos than MAX_GROUP (32)" });
        }
        let mut ids = [0 as Id; MAX_GROUP];
        let asked = self.ids.iter().copied().take(on_bus).chain(extra.as_ref().map(|(id, _)| *id));
        for (slot, id) in ids.iter_mut().zip(asked) {
            *slot = id;
        }
        let mut all = [0i32; MAX_GROUP];
        let held = values.iter().copied().take(on_bus).chain(extra.as_ref().map(|(_, v)| **v));
        for (slot, v) in all.iter_mut().zip(held) {
            *slot = v;
        }
        let ids = ids.get(..count).unwrap_or_default();
        let report = read_values(master, self.model, item, ids, all.get_mut(..count).unwrap_or_default())?;
        let slots = values.iter_mut().take(on_bus).chain(extra.map(|(_, v)| v));
        for (v, x) in slots.zip(all) {
            *v = x;
        }
        Ok(spread(report, on_bus, N))
    }
}

/// A report on `on_bus` servos (and an extra one at bit `on_bus`) as one on `n` joints: the extra
/// servo's bits move to bit `n`, and the padding joints between count as answered.
fn spread(report: GroupReport, on_bus: usize, n: usize) -> GroupReport {
    if on_bus >= n {
        return report;
    }
    let below = |k: usize| 1u32.checked_shl(k as u32).map_or(u32::MAX, |b| b - 1);
    let joints = below(on_bus);
    let padding = below(n) & !joints;
    let moved = |bits: u32| (bits & joints) | ((bits >> on_bus) & 1).checked_shl(n as u32).unwrap_or(0);
    GroupReport {
        count: report.count + (n - on_bus),
        answered: moved(report.answered) | padding,
        alerts: moved(report.alerts),
        failed: moved(report.failed),
        attempts: report.attempts,
    }
}

/// One sync write of `item`, `values[i]` to servo `ids[i]`. Not generic over the group's size, so
/// that every group (the joints, a gripper alone) shares this one body in the firmware's flash.
fn write_values<P, D, C, const BUF: usize>(
    master: &mut Master<P, D, C, BUF>,
    model: &Model,
    item: Item,
    ids: &[Id],
    values: &[i32],
) -> Result<(), PortError<P>>
where
    P: Read + Write + ReadReady,
    D: OutputPin,
    C: Clock,
{
    let mut records = [0u8; MAX_GROUP * 5];
    let mut writer = RecordWriter::new(&mut records);
    let mut value = [0u8; 4];
    for (&id, &v) in ids.iter().zip(values) {
        item.encode(i64::from(v), model.endian, &mut value)
            .map_err(|_| MasterError::BadRequest { reason: "value does not fit the item" })?;
        let bytes = value.get(..item.len()).ok_or(MasterError::BadRequest { reason: "item wider than 4 bytes" })?;
        writer.sync_write(id, bytes).map_err(MasterError::Encode)?;
    }
    master.sync_write(item.address, u16::from(item.size), writer.records())
}

/// One sync read of `item` from servos `ids` into `values` (as many); a servo that did not
/// answer keeps its value. Not generic over the group's size, as [`write_values`].
fn read_values<P, D, C, const BUF: usize>(
    master: &mut Master<P, D, C, BUF>,
    model: &Model,
    item: Item,
    ids: &[Id],
    values: &mut [i32],
) -> Result<GroupReport, PortError<P>>
where
    P: Read + Write + ReadReady,
    D: OutputPin,
    C: Clock,
{
    let mut raw = [0u8; MAX_GROUP * 4];
    let len = item.len();
    let raw = raw.get_mut(..ids.len() * len).unwrap_or_default();
    let report = master.sync_read(item.address, u16::from(item.size), ids, raw)?;
    for (i, (v, bytes)) in values.iter_mut().zip(raw.chunks_exact(len.max(1))).enumerate() {
        if report.answered & 1u32.checked_shl(i as u32).unwrap_or(0) != 0 {
            if let Ok(x) = item.decode(bytes, model.endian) {
                // Only an unsigned 4-byte item can exceed i32; no position item is one.
                *v = x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            }
        }
    }
    Ok(report)
}
