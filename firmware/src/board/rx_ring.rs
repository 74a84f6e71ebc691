//! The bytes a link receive interrupt takes off the UART, kept until the main loop reads them.
//!
//! A UART of the boards holds one received byte (the STM32F411's USART has no FIFO): at 1 Mbps a
//! byte that is not read within 10 µs is overwritten by the next. The main loop cannot read that
//! often: a servo-bus cycle takes about 1 ms (3.5 ms with a servo missing) and a reply up to a few
//! ms to send. So the receive interrupt moves each byte into this ring at once, and the loop
//! drains it between ticks.
//!
//! One producer (the interrupt) and one consumer (the loop), without locks: the producer writes a
//! slot, then publishes it by moving `head` (release); the consumer reads slots up to the `head` it
//! loaded (acquire), then frees them by moving `tail` (release). Every slot is an atomic byte, so
//! no `unsafe` is needed; on the Cortex-M4 these are plain loads and stores. A byte that finds the
//! ring full is dropped and counted: the link's frame check then sees a damaged frame, which the
//! host sends again. The interrupt also counts the UART's receive overruns here ([`RxRing::overrun`]),
//! bytes the hardware lost before the ring saw them, so that both losses reach the firmware's
//! status (`errors.link_dropped`, `errors.link_overruns`) through the main loop.
//!
//! Both counters are `u32` and wrap (the producer adds with `wrapping_add`): at 1 Mbps a host
//! flooding a full ring for 12 hours makes 2^32 drops; a host comparing two statuses takes the
//! difference with `wrapping_sub`.
//!
//! # Panics
//! Nothing here panics: indices are reduced modulo the capacity before use.

use core::sync::atomic::{AtomicU32, AtomicU8, AtomicUsize, Ordering};

/// A byte ring of `N` slots (it holds up to `N - 1` bytes: one slot tells full from empty).
pub struct RxRing<const N: usize> {
    slots: [AtomicU8; N],
    /// The next slot the producer writes.
    head: AtomicUsize,
    /// The next slot the consumer reads.
    tail: AtomicUsize,
    /// Bytes dropped because the ring was full.
    dropped: AtomicU32,
    /// Receive overruns the UART reported (each lost at least one byte before the ring).
    overruns: AtomicU32,
}

impl<const N: usize> Default for RxRing<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RxRing<N> {
    /// An empty ring, usable as a `static`.
    pub const fn new() -> Self {
        #[allow(clippy::declare_interior_mutable_const)]
        const EMPTY: AtomicU8 = AtomicU8::new(0);
        Self {
            slots: [EMPTY; N],
            head: AtomicUsize::new(0),
            tail: AtomicUsize::new(0),
            dropped: AtomicU32::new(0),
            overruns: AtomicU32::new(0),
        }
    }

    /// The slot after `i`.
    fn next(i: usize) -> usize {
        if i + 1 >= N {
            0
        } else {
            i + 1
        }
    }

    /// Producer side (the receive interrupt): keeps `byte`, or drops and counts it when the ring is
    /// full. True if kept.
    pub fn push(&self, byte: u8) -> bool {
        let head = self.head.load(Ordering::Relaxed) % N.max(1);
        let next = Self::next(head);
        if N == 0 || next == self.tail.load(Ordering::Acquire) {
            // Counting needs a read-modify-write, which only this side does: no lost update.
            let dropped = self.dropped.load(Ordering::Relaxed);
            self.dropped.store(dropped.wrapping_add(1), Ordering::Relaxed);
            return false;
        }
        if let Some(slot) = self.slots.get(head) {
            slot.store(byte, Ordering::Relaxed);
        }
        self.head.store(next, Ordering::Release);
        true
    }

    /// Consumer side (the main loop): moves the oldest bytes into `out`; returns how many.
    pub fn pop_into(&self, out: &mut [u8]) -> usize {
        let head = self.head.load(Ordering::Acquire);
        let mut tail = self.tail.load(Ordering::Relaxed) % N.max(1);
        let mut n = 0;
        for byte in out.iter_mut() {
            if tail == head {
                break;
            }
            if let Some(slot) = self.slots.get(tail) {
                *byte = slot.load(Ordering::Relaxed);
            }
            tail = Self::next(tail);
            n += 1;
        }
        self.tail.store(tail, Ordering::Release);
        n
    }

    /// Whether no byte waits.
    pub fn is_empty(&self) -> bool {
        self.head.load(Ordering::Acquire) == self.tail.load(Ordering::Relaxed)
    }

    /// Bytes dropped so far because the ring was full.
    pub fn dropped(&self) -> u32 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Producer side (the receive interrupt): counts one receive overrun of the UART, a byte (or
    /// more) that came while the UART still held the one before, and was lost there.
    pub fn overrun(&self) {
        // As in `push`: only the producer writes the counter.
        let overruns = self.overruns.load(Ordering::Relaxed);
        self.overruns.store(overruns.wrapping_add(1), Ordering::Relaxed);
    }

    /// Receive overruns counted so far ([`RxRing::overrun`]).
    pub fn overruns(&self) -> u32 {
        self.overruns.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_come_out_in_order_across_the_wrap() {
        let ring = RxRing::<8>::new();
        let mut out = [0u8; 5];
        let mut next = 0u8;
        let mut expected = 0u8;
        for _ in 0..20 {
            for _ in 0..5 {
                assert!(ring.push(next));
                next = next.wrapping_add(1);
            }
            assert_eq!(ring.pop_into(&mut out), 5);
            for &b in &out {
                assert_eq!(b, expected);
                expected = expected.wrapping_add(1);
            }
        }
        assert!(ring.is_empty());
        assert_eq!(ring.dropped(), 0);
    }

    #[test]
    fn a_full_ring_drops_and_counts_the_newest() {
        let ring = RxRing::<4>::new();
        assert!(ring.push(1) && ring.push(2) && ring.push(3));
        assert!(!ring.push(4));
        assert_eq!(ring.dropped(), 1);
        let mut out = [0u8; 8];
        assert_eq!(ring.pop_into(&mut out), 3);
        assert_eq!(&out[..3], &[1, 2, 3]);
        assert_eq!(ring.pop_into(&mut out), 0);
        assert!(ring.push(5));
        assert_eq!((ring.pop_into(&mut out), out[0]), (1, 5));
    }

    /// A burst of 1,000 bytes into a ring that holds 511 before the consumer reads: the first 511
    /// are kept in order, the other 489 dropped and counted one by one; overruns are counted apart.
    #[test]
    fn a_burst_beyond_the_ring_counts_every_dropped_byte() {
        let ring = RxRing::<512>::new();
        let kept = (0..1_000u32).filter(|&i| ring.push(i as u8)).count();
        assert_eq!((kept, ring.dropped(), ring.overruns()), (511, 489, 0));
        let mut out = [0u8; 1_000];
        assert_eq!(ring.pop_into(&mut out), 511);
        assert!(out[..511].iter().enumerate().all(|(i, &b)| b == i as u8));
        // Room again: the next bytes are kept, and the count stays.
        assert!(ring.push(7));
        ring.overrun();
        ring.overrun();
        assert_eq!((ring.dropped(), ring.overruns()), (489, 2));
    }

    #[test]
    fn a_small_read_leaves_the_rest() {
        let ring = RxRing::<16>::new();
        for b in 0..10 {
            ring.push(b);
        }
        let mut out = [0u8; 4];
        assert_eq!(ring.pop_into(&mut out), 4);
        assert_eq!(out, [0, 1, 2, 3]);
        assert!(!ring.is_empty());
        let mut rest = [0u8; 16];
        assert_eq!(ring.pop_into(&mut rest), 6);
        assert_eq!(&rest[..6], &[4, 5, 6, 7, 8, 9]);
    }

    #[test]
    fn a_producer_thread_and_a_consumer_thread_lose_nothing() {
        // The interrupt and the main loop as two threads: every byte arrives once, in order.
        static RING: RxRing<64> = RxRing::new();
        const COUNT: u32 = 200_000;
        let producer = std::thread::spawn(|| {
            let mut sent = 0u32;
            while sent < COUNT {
                if RING.push(sent as u8) {
                    sent += 1;
                } else {
                    std::hint::spin_loop();
                }
            }
        });
        let mut got = 0u32;
        let mut out = [0u8; 7];
        while got < COUNT {
            let n = RING.pop_into(&mut out);
            for &b in &out[..n] {
                assert_eq!(b, got as u8, "byte {got}");
                got += 1;
            }
        }
        producer.join().unwrap();
        assert!(RING.is_empty());
    }
}
