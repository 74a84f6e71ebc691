//! A bus master over a fake port whose replies come from the input; see
//! [`firmware_fuzz::master_replies`].
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::master_replies(data));
