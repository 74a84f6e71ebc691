//! The firmware crate's integration tests, one module per file, in one test binary: each
//! binary of its own linked the crate and instantiated its generic code again, which made these
//! tests a fifth of the test build.

mod dxl2_packets;
mod feetech_packets;
mod link_frames;
mod master_half_duplex;
mod stream_props;
