//! The host side of the link protocol ([`firmware::link`]): a client that sends requests with
//! retransmission and keyframe flow control over any byte transport.

pub mod client;
