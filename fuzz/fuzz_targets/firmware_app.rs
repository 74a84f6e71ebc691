//! The firmware application fed arbitrary host bytes and servo replies; see
//! [`firmware_fuzz::firmware_app`].
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::firmware_app(data));
