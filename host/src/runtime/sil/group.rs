//! Several simulated boards on one virtual clock: a rig of arms in software in the loop, each arm
//! with its own firmware core, its own servo bus and its own host link, as on real boards, and
//! one time line for all of them.
//!
//! [`SilGroup`] owns the boards; each [`SilMember`] is one host link's end (a byte transport for
//! [`crate::link::client::LinkClient`], like [`Sil`] itself). Whichever link the host waits on,
//! every board runs, event by event in time order, so no board's clock runs ahead of another's:
//! two `Start`s sent one after the other start their players one link round trip apart, as on
//! two boards plugged into one PC. The host is single-threaded here, as with one [`Sil`].

use std::cell::{RefCell, RefMut};
use std::io::{self, Read, Write};
use std::rc::Rc;

use anyhow::{bail, Result};

use super::{read_in_step, run_in_step, Sil};

/// Boards on one virtual clock.
#[derive(Clone)]
pub struct SilGroup {
    sils: Rc<RefCell<Vec<Sil>>>,
}

impl SilGroup {
    /// The boards `sils`, from now on in step; refused unless they all stand at the same time
    /// (as new ones do, at 0).
    pub fn new(sils: Vec<Sil>) -> Result<Self> {
        if let Some(first) = sils.first() {
            if sils.iter().any(|s| s.clock.now_ns() != first.clock.now_ns()) {
                bail!("the simulated boards of a group must start at the same virtual time");
            }
        }
        Ok(Self { sils: Rc::new(RefCell::new(sils)) })
    }

    /// How many boards.
    pub fn len(&self) -> usize {
        self.sils.borrow().len()
    }

    /// Whether the group has no board.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The host end of board `index`'s link; `None` past the last board.
    pub fn member(&self, index: usize) -> Option<SilMember> {
        (index < self.len()).then(|| SilMember { sils: Rc::clone(&self.sils), index })
    }

    /// Board `index` (to record its ticks, put an object before it, read its monitor); panics past
    /// the last board, and while a link of the group reads (the host is single-threaded).
    pub fn board(&self, index: usize) -> RefMut<'_, Sil> {
        RefMut::map(self.sils.borrow_mut(), |sils| &mut sils[index])
    }

    /// Virtual time, s (the same on every board).
    pub fn now_s(&self) -> f64 {
        self.sils.borrow().first().map_or(0.0, Sil::now_s)
    }

    /// Lets `seconds` of virtual time pass on every board, the host silent.
    pub fn run_for(&self, seconds: f64) {
        run_in_step(&mut self.sils.borrow_mut(), seconds);
    }

    /// [`Sil::settle_reads`] on every board at once.
    pub fn settle_reads(&self) {
        super::settle_reads(&mut self.sils.borrow_mut());
    }
}

/// The host end of one board's link in a [`SilGroup`].
pub struct SilMember {
    sils: Rc<RefCell<Vec<Sil>>>,
    index: usize,
}

impl Read for SilMember {
    /// The bytes that have arrived from this board, after running every board of the group until
    /// one does; `TimedOut` after this board's read timeout of virtual time without any.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        read_in_step(&mut self.sils.borrow_mut(), self.index, buf)
    }
}

impl Write for SilMember {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.sils.borrow_mut()[self.index].write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
