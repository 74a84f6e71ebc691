//! Every named control-table item of a model, so that a read of raw bytes can be shown decoded and
//! a write can take the width and encoding of the item at its address.
//!
//! [`Model::items`] holds only the items the firmware uses, by role; the tables' modules define
//! more (LED, drive mode, voltage...). The lists here gather those constants; they are not a second
//! table.

use firmware::bus::table::{sts3215, xseries, Item, Model};
use firmware::bus::Protocol;

/// The X-series items (the three models share their addresses).
const XSERIES: [Item; 30] = [
    xseries::MODEL_NUMBER,
    xseries::FIRMWARE_VERSION,
    xseries::ID,
    xseries::BAUD_RATE,
    xseries::RETURN_DELAY_TIME,
    xseries::DRIVE_MODE,
    xseries::OPERATING_MODE,
    xseries::HOMING_OFFSET,
    xseries::TEMPERATURE_LIMIT,
    xseries::MAX_VOLTAGE_LIMIT,
    xseries::MIN_VOLTAGE_LIMIT,
    xseries::PWM_LIMIT,
    xseries::VELOCITY_LIMIT,
    xseries::MAX_POSITION_LIMIT,
    xseries::MIN_POSITION_LIMIT,
    xseries::TORQUE_ENABLE,
    xseries::LED,
    xseries::STATUS_RETURN_LEVEL,
    xseries::REGISTERED_INSTRUCTION,
    xseries::HARDWARE_ERROR_STATUS,
    xseries::POSITION_D_GAIN,
    xseries::POSITION_P_GAIN,
    xseries::PROFILE_ACCELERATION,
    xseries::PROFILE_VELOCITY,
    xseries::GOAL_POSITION,
    xseries::MOVING,
    xseries::PRESENT_VELOCITY,
    xseries::PRESENT_POSITION,
    xseries::PRESENT_INPUT_VOLTAGE,
    xseries::PRESENT_TEMPERATURE,
];

/// The STS3215 items.
const STS3215: [Item; 27] = [
    sts3215::FIRMWARE_MAJOR_VERSION,
    sts3215::FIRMWARE_MINOR_VERSION,
    sts3215::MODEL_NUMBER,
    sts3215::ID,
    sts3215::BAUD_RATE,
    sts3215::RETURN_DELAY_TIME,
    sts3215::RESPONSE_STATUS_LEVEL,
    sts3215::MIN_POSITION_LIMIT,
    sts3215::MAX_POSITION_LIMIT,
    sts3215::P_COEFFICIENT,
    sts3215::D_COEFFICIENT,
    sts3215::I_COEFFICIENT,
    sts3215::HOMING_OFFSET,
    sts3215::OPERATING_MODE,
    sts3215::TORQUE_ENABLE,
    sts3215::ACCELERATION,
    sts3215::GOAL_POSITION,
    sts3215::GOAL_TIME,
    sts3215::GOAL_VELOCITY,
    sts3215::LOCK,
    sts3215::PRESENT_POSITION,
    sts3215::PRESENT_VELOCITY,
    sts3215::PRESENT_LOAD,
    sts3215::PRESENT_VOLTAGE,
    sts3215::PRESENT_TEMPERATURE,
    sts3215::MOVING,
    sts3215::MAXIMUM_ACCELERATION,
];

/// The named items of `model`, in address order.
pub fn all(model: &Model) -> &'static [Item] {
    // Every model of a protocol shares one table today (X-series on Dynamixel, STS3215 on
    // Feetech); a test checks each model's role items are in its list.
    match model.protocol {
        Protocol::Dxl2 => &XSERIES,
        Protocol::Feetech => &STS3215,
    }
}

/// The item that starts at `address`, if any.
pub fn at(model: &Model, address: u16) -> Option<Item> {
    all(model).iter().copied().find(|i| i.address == address)
}

/// The item named `name` (as armctl prints it: `present_position`), if the model has it.
pub fn named(model: &Model, name: &str) -> Option<Item> {
    all(model).iter().copied().find(|i| i.name == name)
}

/// The items that lie wholly inside `len` bytes from `address`, in address order.
pub fn within(model: &Model, address: u16, len: usize) -> impl Iterator<Item = Item> {
    let start = usize::from(address);
    all(model)
        .iter()
        .copied()
        .filter(move |i| usize::from(i.address) >= start && usize::from(i.address) + i.len() <= start + len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::bus::table::MODELS;

    #[test]
    fn every_role_item_is_listed() {
        for model in MODELS {
            let i = model.items;
            let roles = [
                i.model_number,
                i.firmware,
                i.id,
                i.baud,
                i.return_delay,
                i.min_position,
                i.max_position,
                i.torque_enable,
                i.status_return_level,
                i.acceleration,
                i.velocity,
                i.goal_position,
                i.moving,
                i.present_position,
            ];
            for item in roles.iter().chain(i.hardware_error.iter()).chain(i.lock.iter()) {
                assert!(all(model).contains(item), "{}: {} missing", model.name, item.name);
            }
        }
    }

    #[test]
    fn lists_are_in_address_order_without_overlap() {
        for model in MODELS {
            for pair in all(model).windows(2) {
                assert!(pair[0].address + u16::from(pair[0].size) <= pair[1].address, "{}: {:?}", model.name, pair);
            }
        }
    }

    #[test]
    fn finds_items_inside_a_range() {
        let model = &firmware::bus::table::XL430_W250;
        let names: Vec<_> = within(model, 128, 8).map(|i| i.name).collect();
        assert_eq!(names, ["present_velocity", "present_position"]);
        assert_eq!(at(model, 116).map(|i| i.name), Some("goal_position"));
        assert_eq!(within(model, 133, 3).count(), 0);
        assert_eq!(named(model, "present_position").map(|i| i.address), Some(132));
        assert_eq!(named(&firmware::bus::table::STS3215, "present_load").map(|i| (i.address, i.size)), Some((60, 2)));
        assert!(named(model, "present_lod").is_none());
    }
}
