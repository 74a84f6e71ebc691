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
}

impl<const N: usize> ServoGroup<N> {
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
        if N + usize::from(extra.is_some()) > MAX_GROUP {
            return Err(MasterError::BadRequest { reason: "more servos than MAX_GROUP (32)" });
        }
        let mut records = [0u8; MAX_GROUP * 5];
        let mut writer = RecordWriter::new(&mut records);
        let mut value = [0u8; 4];
        for (id, v) in self.ids.iter().copied().zip(values.iter().copied()).chain(extra) {
            item.encode(i64::from(v), self.model.endian, &mut value)
                .map_err(|_| MasterError::BadRequest { reason: "value does not fit the item" })?;
            writer.sync_write(id, &value[..item.len()]).map_err(MasterError::Encode)?;
        }
        let len = writer.records().len();
        master.sync_write(item.address, u16::from(item.size), &records[..len])
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
    /// where its value goes); the report's bit `N` is that servo's.
    pub fn read_with<P, D, C, const BUF: usize>(
        &self,
        master: &mut Master<P, D, C, BUF>,
        item: Item,
        values: &mut [i32; N],
        mut extra: Option<(Id, &mut i32)>,
    ) -> Result<GroupReport, PortError<P>>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let count = N + usize::from(extra.is_some());
        if count > MAX_GROUP {
            return Err(MasterError::BadRequest { reason: "more servos than MAX_GROUP (32)" });
        }
        let mut ids = [0 as Id; MAX_GROUP];
        for (slot, id) in ids.iter_mut().zip(self.ids.iter().copied().chain(extra.as_ref().map(|(id, _)| *id))) {
            *slot = id;
        }
        let mut raw = [0u8; MAX_GROUP * 4];
        let len = item.len();
        let raw = raw.get_mut(..count * len).unwrap_or_default();
        let report = master.sync_read(item.address, u16::from(item.size), ids.get(..count).unwrap_or_default(), raw)?;
        let slots = values.iter_mut().chain(extra.as_mut().map(|(_, v)| &mut **v));
        for (i, (v, bytes)) in slots.zip(raw.chunks_exact(len.max(1))).enumerate() {
            if report.answered & (1 << i) != 0 {
                if let Ok(x) = item.decode(bytes, self.model.endian) {
                    // Only an unsigned 4-byte item can exceed i32; no position item is one.
                    *v = x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
                }
            }
        }
        Ok(report)
    }
}
