//! One frame: parse, encode, parse again; see [`firmware_fuzz::roundtrip_feetech`].
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::roundtrip_feetech(data));
