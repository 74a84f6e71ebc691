//! Arbitrary bytes into the streaming decoder, byte by byte and in bursts; see
//! [`firmware_fuzz::stream`].
#![no_main]

use firmware::bus::Protocol;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::stream(Protocol::Feetech, data));
