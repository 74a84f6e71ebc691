//! Arbitrary bytes into the host link's frame decoder and message decoders; see
//! [`firmware_fuzz::link_frames`].
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::link_frames(data));
