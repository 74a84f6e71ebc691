//! A calibration written into an arm file a person already has ([`super::toml_file`]), keeping
//! what they wrote: their comments, their units (degrees stay degrees), their DH table, their
//! layout, byte for byte. Only the keys a calibration sets change:
//!
//! - in `[servos]`: `homing_offset`, `range_min` and `range_max` (an array of the same length keeps
//!   its layout, only the numbers change); `reversed`, which with a calibration is LeRobot's
//!   `drive_mode`, when a drive mode is 1; and `zero`, which does not apply with a calibration;
//! - in `[gripper]`: `closed` and `open`.
//!
//! A `zero`, or a `reversed` the calibration does not need, is not deleted but kept as a comment
//! line with a note, so the person can see what it was. The joints' limits are not touched: loading
//! the file tightens them to the calibrated ranges (see [`super::toml_file`]).
//!
//! [`check`] refuses what cannot be updated safely, before anything is measured or written: a
//! URDF, a file that is not an arm file, or an arm file of another arm (other joints, servos or
//! gripper). [`with_calibration`] checks again and checks its own result: the new text must load
//! as the same arm with the new calibration.

use anyhow::{anyhow, bail, Result};
use toml_edit::{Array, DocumentMut, Item, Table, Value};

use super::servos::ServoSetup;
use super::ArmSpec;

/// Checks that `text` (an existing `--out` file) is an arm file of `arm` that a calibration can be
/// written into, and returns the arm it holds. The error is one line saying why it is not.
pub fn check(text: &str, arm: &ArmSpec) -> Result<ArmSpec> {
    if text.trim_start().starts_with('<') {
        bail!("it is a URDF (XML), not an arm file (TOML)");
    }
    let existing = super::toml_file::parse(text).map_err(|e| anyhow!("it is not an arm file armctl reads ({e:#})"))?;
    text.parse::<DocumentMut>().map_err(|e| anyhow!("it is not TOML ({})", one_line(&e.to_string())))?;
    let (theirs, ours) = (describe(&existing), describe(arm));
    if theirs != ours {
        bail!("it is another arm: {} has {theirs}, {} has {ours}", existing.name, arm.name);
    }
    Ok(existing)
}

/// `text`, an arm file of `calibrated` ([`check`]), with `calibrated`'s calibration written in
/// (the module doc says what changes), and the arm the new text loads as.
pub fn with_calibration(text: &str, calibrated: &ArmSpec) -> Result<(String, ArmSpec)> {
    check(text, calibrated)?;
    let servos = calibrated.servos.as_ref().ok_or_else(|| anyhow!("arm {} has no servos", calibrated.name))?;
    let calibration =
        servos.calibration.as_ref().ok_or_else(|| anyhow!("arm {} holds no calibration", calibrated.name))?;
    let mut doc: DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| anyhow!("{e}"))?;

    let field = |f: fn(&super::calibration::MotorCalibration) -> i32| -> Vec<Value> {
        calibration.iter().map(|m| Value::from(i64::from(f(m)))).collect()
    };
    let drive_modes: Vec<Value> = calibration.iter().map(|m| Value::from(m.drive_mode == 1)).collect();
    let reversed = calibration.iter().any(|m| m.drive_mode == 1);
    let table = doc.get_mut("servos").ok_or_else(|| anyhow!("it has no [servos] table"))?;
    match table {
        Item::Table(t) => {
            set_array(t, "homing_offset", field(|m| m.homing_offset));
            set_array(t, "range_min", field(|m| m.range_min));
            set_array(t, "range_max", field(|m| m.range_max));
            if reversed {
                set_array(t, "reversed", drive_modes);
            } else {
                comment_out(t, "reversed", "with a calibration it is LeRobot's drive_mode, 0 for every servo here");
            }
            comment_out(t, "zero", "it does not apply with a calibration (the zero is the calibrated range's middle)");
        }
        Item::Value(Value::InlineTable(t)) => {
            for (key, values) in [
                ("homing_offset", field(|m| m.homing_offset)),
                ("range_min", field(|m| m.range_min)),
                ("range_max", field(|m| m.range_max)),
            ] {
                set_value(t.entry(key).or_insert(Value::Array(Array::new())), values);
            }
            if reversed {
                set_value(t.entry("reversed").or_insert(Value::Array(Array::new())), drive_modes);
            } else {
                t.remove("reversed");
            }
            t.remove("zero");
        }
        _ => bail!("its servos are not a table"),
    }
    if let Some(gripper) = servos.gripper {
        let table = doc.get_mut("gripper").and_then(Item::as_table_like_mut);
        let table = table.ok_or_else(|| anyhow!("it has no [gripper] table"))?;
        for (key, ticks) in [("closed", gripper.closed), ("open", gripper.open)] {
            match table.get_mut(key).and_then(Item::as_value_mut) {
                Some(value) => replace_keeping_decor(value, Value::from(i64::from(ticks))),
                None => bail!("its [gripper] has no {key}"),
            }
        }
    }

    let out = doc.to_string();
    let arm = super::toml_file::parse(&out).map_err(|e| anyhow!("the updated file would not load ({e:#})"))?;
    let loaded = arm.servos.as_ref();
    if loaded.and_then(|s| s.calibration.as_ref()) != Some(calibration)
        || loaded.and_then(|s| s.gripper).map(|g| (g.closed, g.open)) != servos.gripper.map(|g| (g.closed, g.open))
    {
        bail!("the updated file would not load with the new calibration");
    }
    Ok((out, arm))
}

/// What makes two arm files the same arm for a calibration: the joints by name, the servos'
/// model and ids, the gripper's id.
fn describe(arm: &ArmSpec) -> String {
    let names: Vec<&str> = arm.joints.iter().map(|j| j.name.as_str()).collect();
    let servos = match &arm.servos {
        None => "no [servos] table".to_string(),
        Some(ServoSetup { model, ids, gripper, .. }) => {
            let ids: Vec<String> = ids.iter().map(u8::to_string).collect();
            let gripper = gripper.map(|g| format!(", gripper servo {}", g.id)).unwrap_or_default();
            format!("{} servos {}{gripper}", model.name, ids.join(", "))
        }
    };
    format!("joints {}; {servos}", names.join(", "))
}

/// `key` of `table` set to `values`: an array of the same length keeps its layout and comments
/// (each element replaced in place), anything else is replaced keeping the key's own decor; a
/// missing key is added at the end of the table.
fn set_array(table: &mut Table, key: &str, values: Vec<Value>) {
    match table.get_mut(key).and_then(Item::as_value_mut) {
        Some(value) => set_value(value, values),
        None => {
            table.insert(key, Item::Value(Value::Array(values.into_iter().collect())));
        }
    }
}

fn set_value(value: &mut Value, values: Vec<Value>) {
    match value.as_array_mut() {
        Some(array) if array.len() == values.len() => {
            for (i, v) in values.into_iter().enumerate() {
                array.replace(i, v);
            }
        }
        _ => replace_keeping_decor(value, Value::Array(values.into_iter().collect())),
    }
}

/// `value` replaced by `new`, the spaces and comment around it kept.
fn replace_keeping_decor(value: &mut Value, mut new: Value) {
    *new.decor_mut() = value.decor().clone();
    *value = new;
}

/// Removes `key` from `table`, keeping its line (and the comments above it) as comment lines
/// after a note, where it was: before the next key, or, for the table's last key, before
/// `homing_offset` (which a calibration always sets).
fn comment_out(table: &mut Table, key: &str, note: &str) {
    let keys: Vec<String> = table.iter().map(|(k, _)| k.to_string()).collect();
    let Some(i) = keys.iter().position(|k| k == key) else { return };
    let prefix = decor_prefix(table, key);
    let value = table.get(key).and_then(Item::as_value).map(|v| v.to_string()).unwrap_or_default();
    let kept = format!("{prefix}# armctl calibrate took out `{key}`: {note}\n# {key} ={value}\n");
    table.remove(key);
    let next = keys.get(i + 1).map_or("homing_offset", String::as_str);
    let after = decor_prefix(table, next);
    if let Some(mut k) = table.key_mut(next) {
        k.leaf_decor_mut().set_prefix(format!("{kept}{after}"));
    }
}

/// The text before `key` on its line and the lines above it that belong to it (blank lines,
/// comments).
fn decor_prefix(table: &Table, key: &str) -> String {
    let prefix = table.key(key).and_then(|k| k.leaf_decor().prefix().and_then(|p| p.as_str().map(str::to_string)));
    prefix.unwrap_or_default()
}

fn one_line(text: &str) -> String {
    text.split('\n').map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{record, MotorCalibration};

    /// A person's arm: DH in degrees, comments everywhere, a `zero` and a `reversed`.
    const MINE: &str = r#"# My three-joint arm, measured with calipers.
name = "mine"
convention = "dh"
angles = "degrees"   # the limits too

[[joint]]
name = "pan"
type = "revolute"
a = 0
alpha = 90   # the shoulder axis is horizontal
d = 0.08
limits = [-150, 150]

[[joint]]
name = "lift"
type = "revolute"
a = 0.12
alpha = 0
d = 0
limits = [-90, 90]

[servos]
model = "STS3215"
ids = [
    7,  # pan
    8,  # lift
]
# the middle of each horn, measured by hand
zero = [2048, 1900]
reversed = [false, true]  # the lift servo is upside down
max_velocity = 2.0   # slow for now
max_acceleration = 8.0

[gripper]
id = 9
closed = 2000  # fully shut
open = 3000
opening_mm = 40
"#;

    fn calibrated(drive_mode: u8) -> ArmSpec {
        let arm = crate::toml_file::parse(MINE).unwrap();
        let servos = arm.servos.clone().unwrap();
        let joints = [
            MotorCalibration { id: 7, drive_mode: 0, homing_offset: 953, range_min: 900, range_max: 3100 },
            MotorCalibration { id: 8, drive_mode, homing_offset: -12, range_min: 1500, range_max: 2600 },
        ];
        let gripper = MotorCalibration { id: 9, drive_mode: 0, homing_offset: 5, range_min: 2100, range_max: 3300 };
        record::calibrated_arm(&arm, &servos, &joints, Some(&gripper)).unwrap()
    }

    #[test]
    fn only_the_servos_keys_change_and_the_rest_stays_byte_for_byte() {
        let arm = calibrated(0);
        let (text, loaded) = with_calibration(MINE, &arm).unwrap();
        let servos_at = MINE.find("[servos]").unwrap();
        assert_eq!(text[..servos_at], MINE[..servos_at], "everything before [servos] as it was");
        let want = r#"[servos]
model = "STS3215"
ids = [
    7,  # pan
    8,  # lift
]
# the middle of each horn, measured by hand
# armctl calibrate took out `zero`: it does not apply with a calibration (the zero is the calibrated range's middle)
# zero = [2048, 1900]
# armctl calibrate took out `reversed`: with a calibration it is LeRobot's drive_mode, 0 for every servo here
# reversed = [false, true]  # the lift servo is upside down
max_velocity = 2.0   # slow for now
max_acceleration = 8.0
homing_offset = [953, -12]
range_min = [900, 1500]
range_max = [3100, 2600]

[gripper]
id = 9
closed = 2100  # fully shut
open = 3300
opening_mm = 40
"#;
        assert_eq!(&text[servos_at..], want);
        assert_eq!(loaded.servos.as_ref().unwrap().calibration, arm.servos.as_ref().unwrap().calibration);
        // The limits are the file's (degrees), tightened at load as a new file's are.
        let fresh = crate::toml_file::parse(&crate::toml_writer::to_text(&arm, &[])).unwrap();
        for (a, b) in loaded.joints.iter().zip(&fresh.joints) {
            assert!((a.lower - b.lower).abs() < 1e-12 && (a.upper - b.upper).abs() < 1e-12, "{a:?} {b:?}");
        }
        // Again: the same text.
        assert_eq!(with_calibration(&text, &arm).unwrap().0, text);
        // A new calibration changes the numbers only, in place.
        let mut again = arm.clone();
        again.servos.as_mut().unwrap().calibration.as_mut().unwrap()[0].range_min = 1000;
        let (third, _) = with_calibration(&text, &again).unwrap();
        assert_eq!(third, text.replace("range_min = [900, 1500]", "range_min = [1000, 1500]"));
    }

    #[test]
    fn a_drive_mode_of_1_is_written_as_reversed() {
        let (text, loaded) = with_calibration(MINE, &calibrated(1)).unwrap();
        assert!(text.contains("reversed = [false, true]  # the lift servo is upside down\n"), "{text}");
        assert_eq!(loaded.servos.unwrap().calibration.unwrap()[1].drive_mode, 1);
    }

    #[test]
    fn what_cannot_be_updated_is_refused_in_one_line() {
        let arm = calibrated(0);
        let urdf = "<?xml version=\"1.0\"?>\n<robot name=\"mine\"></robot>\n";
        for (text, needle) in [
            (urdf.to_string(), "it is a URDF (XML), not an arm file (TOML)"),
            ("name = \"mine\"\n[[joint]\n".to_string(), "it is not an arm file armctl reads (line 2"),
            ("[package]\nname = \"x\"\n".to_string(), "unknown field `package`"),
            (
                MINE.replace("ids = [\n    7,", "ids = [\n    17,"),
                "it is another arm: mine has joints pan, lift; STS3215 servos 17, 8, gripper servo 9, mine has joints \
                 pan, lift; STS3215 servos 7, 8, gripper servo 9",
            ),
        ] {
            let e = format!("{:#}", with_calibration(&text, &arm).unwrap_err());
            assert!(e.contains(needle) && !e.contains('\n'), "{needle:?} in {e:?}");
        }
        let preset = crate::presets::by_name("so101").unwrap();
        let e = check(MINE, &ArmSpec { servos: crate::servos::ServoSetup::for_arm("so101"), ..preset }).unwrap_err();
        assert!(e.to_string().contains("it is another arm: mine has joints pan, lift;"), "{e}");
    }
}
