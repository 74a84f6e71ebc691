//! Wire time: how long bytes take on the bus. A UART frame is 10 bits per byte (start bit, 8 data
//! bits, stop bit), so a byte takes `10 / baud` seconds. The software-in-the-loop clock charges the
//! same arithmetic, and the controller's cycle is checked against [`cycle_bytes`], the least the
//! protocol needs for one control cycle.

use super::Protocol;

/// Bits on the wire per byte: start, 8 data, stop.
pub const BITS_PER_BYTE: u64 = 10;

/// Nanoseconds `bytes` take at `baud` (rounded up; 0 baud is treated as 1).
pub fn wire_time_ns(bytes: usize, baud: u32) -> u64 {
    wire_time(bytes, baud, 9)
}

/// Microseconds `bytes` take at `baud`, rounded up: the nanoseconds rounded up to whole
/// microseconds (rounding up twice is rounding up once).
pub fn wire_time_us(bytes: usize, baud: u32) -> u64 {
    wire_time(bytes, baud, 6)
}

/// `ceil(bits * 10^digits / baud)`, exactly, by long division one decimal digit at a time. Only
/// 32-bit divisions: the M4F divides 32 bits in hardware, and a 64-bit division would link
/// compiler_builtins' 900-byte routine into the firmware. Bauds above 100 Mbps (no serial bus
/// runs there) count as 100 Mbps, so that ten times a remainder always fits 32 bits.
fn wire_time(bytes: usize, baud: u32, digits: u32) -> u64 {
    let baud = baud.clamp(1, 100_000_000);
    let bits = u32::try_from(bytes).unwrap_or(u32::MAX).saturating_mul(BITS_PER_BYTE as u32);
    let mut quotient = u64::from(bits / baud);
    let mut remainder = bits % baud;
    for _ in 0..digits {
        let next = remainder * 10;
        quotient = quotient.saturating_mul(10).saturating_add(u64::from(next / baud));
        remainder = next % baud;
    }
    quotient + u64::from(remainder > 0)
}

/// Parameter bytes ahead of the per-servo records in a sync read or sync write: address and
/// length, two bytes each on Dynamixel, one each on Feetech.
pub fn sync_header_len(protocol: Protocol) -> usize {
    match protocol {
        Protocol::Dxl2 => 4,
        Protocol::Feetech => 2,
    }
}

/// Bytes of a sync write of `value_len` bytes to each of `servos` servos (unstuffed: the least).
pub fn sync_write_len(protocol: Protocol, servos: usize, value_len: usize) -> usize {
    protocol.instruction_len(sync_header_len(protocol) + servos * (1 + value_len))
}

/// Bytes of a sync read request to `servos` servos.
pub fn sync_read_request_len(protocol: Protocol, servos: usize) -> usize {
    protocol.instruction_len(sync_header_len(protocol) + servos)
}

/// The bytes of one control cycle: a sync write of goals, a sync read request of positions and
/// one status reply of `position_len` bytes per servo.
pub fn cycle_bytes(protocol: Protocol, servos: usize, goal_len: usize, position_len: usize) -> usize {
    sync_write_len(protocol, servos, goal_len)
        + sync_read_request_len(protocol, servos)
        + servos * protocol.status_len(position_len)
}

/// Nanoseconds of one control cycle on the wire plus each servo's return delay: the shortest
/// period at which the cycle can repeat.
pub fn cycle_time_ns(
    protocol: Protocol,
    servos: usize,
    goal_len: usize,
    position_len: usize,
    baud: u32,
    return_delay_us: u32,
) -> u64 {
    wire_time_ns(cycle_bytes(protocol, servos, goal_len, position_len), baud)
        + (servos as u64) * u64::from(return_delay_us) * 1000
}

/// [`cycle_time_ns`] in microseconds, rounded up (what the firmware checks its period against).
pub fn cycle_time_us(
    protocol: Protocol,
    servos: usize,
    goal_len: usize,
    position_len: usize,
    baud: u32,
    return_delay_us: u32,
) -> u64 {
    wire_time_us(cycle_bytes(protocol, servos, goal_len, position_len), baud)
        + (servos as u64) * u64::from(return_delay_us)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worked figures of shared/reference/protocols.md ("Wire time").
    #[test]
    fn reference_cycle_figures() {
        assert_eq!(sync_write_len(Protocol::Dxl2, 6, 4), 44);
        assert_eq!(sync_read_request_len(Protocol::Dxl2, 6), 20);
        assert_eq!(Protocol::Dxl2.status_len(4), 15);
        assert_eq!(cycle_bytes(Protocol::Dxl2, 6, 4, 4), 154);
        assert_eq!(wire_time_ns(154, 1_000_000), 1_540_000);
        // 26.7 ms at 57600 baud.
        assert_eq!(wire_time_ns(154, 57_600) / 100_000, 267);
        assert_eq!(cycle_bytes(Protocol::Feetech, 6, 2, 2), 88);
        assert_eq!(wire_time_ns(88, 1_000_000), 880_000);
        assert_eq!(cycle_time_ns(Protocol::Dxl2, 6, 4, 4, 1_000_000, 500), 1_540_000 + 3_000_000);
        assert_eq!(cycle_time_us(Protocol::Dxl2, 6, 4, 4, 1_000_000, 500), 1_540 + 3_000);
    }

    /// The digit-by-digit division equals the plain 64-bit one, rounding included, over byte
    /// counts and bauds from the slowest to beyond the fastest servo bus; microseconds are the
    /// nanoseconds rounded up.
    #[test]
    fn long_division_matches_64_bit_arithmetic() {
        let bauds = [1, 7, 9_600, 57_600, 115_200, 1_000_000, 3_000_000, 4_500_000, 99_999_989, 100_000_000];
        for baud in bauds {
            for bytes in (0..2_000).chain([65_535, 1 << 24]) {
                let bits = bytes as u64 * BITS_PER_BYTE;
                let ns = (bits * 1_000_000_000).div_ceil(u64::from(baud));
                assert_eq!(wire_time_ns(bytes, baud), ns, "{bytes} bytes at {baud}");
                assert_eq!(wire_time_us(bytes, baud), ns.div_ceil(1000), "{bytes} bytes at {baud}");
            }
        }
        assert_eq!(wire_time_ns(10, 0), 100_000_000_000);
    }
}
