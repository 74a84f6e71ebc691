//! Which arm `armctl --arm ARM` sends to a firmware that already runs one
//! ([`handshake_with`]): the arm is known by its digest, not its name. Run against the firmware
//! core in software in the loop, which answers the link exactly as a board does.

use armctl::arm::servos::servos_of;
use armctl::arm::ArmSpec;
use armctl::link::arm_config::arm_digest;
use armctl::link::session::Session;
use armctl::runtime::connection::handshake_with;
use armctl::runtime::sil::{Sil, SilOptions};

/// The SO-101 with its servos' zero offsets moved (as a calibration does): the same name, another
/// arm.
fn recalibrated(offset: i32) -> ArmSpec {
    let mut arm = ArmSpec::load("so101", None).unwrap();
    let mut servos = servos_of(&arm).unwrap();
    servos.zero = Some(vec![2048 + offset; 5]);
    arm.servos = Some(servos);
    arm
}

#[test]
fn a_board_is_sent_the_arm_it_does_not_run_and_never_loses_one_sent_by_another() {
    let mut c = Session::over(Sil::new(&SilOptions::new("so101").unwrap()).unwrap());
    // The preset as shipped, but for its collision geometry (the built-in arm carries none), is
    // what the built-in arm is: nothing to send.
    let shipped = ArmSpec { collision: None, ..ArmSpec::load("so101", None).unwrap() };
    let (info, _) = handshake_with(&mut c, Some(shipped)).unwrap();
    assert_eq!(info.arm_digest, firmware::builtin::DIGEST);
    // A calibrated SO-101 of the same name replaces the built-in arm.
    let first = recalibrated(10);
    let digest = arm_digest(&first, &servos_of(&first).unwrap()).unwrap();
    assert_ne!(digest, firmware::builtin::DIGEST);
    let (info, _) = handshake_with(&mut c, Some(first.clone())).unwrap();
    assert_eq!((info.arm_name.as_str(), info.arm_digest), ("so101", digest));
    // Connecting again with it: it runs already.
    let (info, _) = handshake_with(&mut c, Some(first)).unwrap();
    assert_eq!(info.arm_digest, digest);
    // Another one of the name is not sent over it: one line that says what to do.
    let error = handshake_with(&mut c, Some(recalibrated(-10))).unwrap_err().to_string();
    assert!(error.contains("runs another arm named so101") && error.contains("a name of its own"), "{error}");
    assert_eq!(c.hello().unwrap().arm_digest, digest, "the arm it ran is kept");
    // Nor the preset as shipped: only the built-in arm gives way.
    assert!(handshake_with(&mut c, Some(ArmSpec::load("so101", None).unwrap())).is_err());
}
