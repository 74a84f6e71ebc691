//! LeRobot's calibration file: one JSON object keyed by motor name, each value
//! `{"id", "drive_mode", "homing_offset", "range_min", "range_max"}` (integers, raw ticks), written
//! by Python's `json.dump(..., indent=4)` in the motors' order. Read strictly (LeRobot builds a
//! `MotorCalibration(**value)` from each entry, which refuses a missing or unknown field), written
//! the way LeRobot writes it, so that a file goes back and forth unchanged.
//!
//! Where LeRobot keeps them: `$HF_LEROBOT_CALIBRATION`, else `$HF_HOME/lerobot/calibration`
//! (`HF_HOME` defaulting to `~/.cache/huggingface`), then `robots/<type>/<id>.json` or
//! `teleoperators/<type>/<id>.json`.

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use serde::de::{MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::Value;

use super::{Calibration, MotorCalibration};

/// The fields of an entry, in LeRobot's order (its dataclass's).
const FIELDS: [&str; 5] = ["id", "drive_mode", "homing_offset", "range_min", "range_max"];

/// Keys of the older format (one array per field, motors by position), which is not read.
const OLD_FORMAT_KEYS: [&str; 5] = ["homing_offset", "drive_mode", "start_pos", "end_pos", "calib_mode"];

/// A JSON object's entries in the file's order.
struct Ordered(Vec<(String, Value)>);

impl<'de> Deserialize<'de> for Ordered {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> Visitor<'de> for Entries {
            type Value = Ordered;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object keyed by motor name")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Ordered, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry::<String, Value>()? {
                    entries.push(entry);
                }
                Ok(Ordered(entries))
            }
        }
        deserializer.deserialize_map(Entries)
    }
}

/// One integer field of motor `name`'s entry, within `lo..=hi`.
fn field(name: &str, entry: &serde_json::Map<String, Value>, key: &str, lo: i64, hi: i64) -> Result<i64> {
    let value = entry.get(key).ok_or_else(|| anyhow!("motor {name:?}: no {key:?}"))?;
    let n = value.as_i64().ok_or_else(|| anyhow!("motor {name:?}: {key:?} is {value}, not an integer"))?;
    if !(lo..=hi).contains(&n) {
        bail!("motor {name:?}: {key:?} {n} is outside {lo}..={hi}");
    }
    Ok(n)
}

/// Reads a LeRobot calibration file's text; the calibration is checked ([`Calibration::check`]).
pub fn parse(text: &str) -> Result<Calibration> {
    let Ordered(entries) = serde_json::from_str(text).map_err(|e| anyhow!("not a LeRobot calibration: {e}"))?;
    if entries.iter().any(|(k, v)| OLD_FORMAT_KEYS.contains(&k.as_str()) && v.is_array()) {
        bail!(
            "this is LeRobot's older calibration format (arrays homing_offset, drive_mode, start_pos, end_pos, \
             calib_mode), which is not read: calibrate again with a current LeRobot or with armctl"
        );
    }
    let mut motors = Vec::with_capacity(entries.len());
    for (name, value) in entries {
        let entry = value.as_object().ok_or_else(|| anyhow!("motor {name:?}: {value} is not an object"))?;
        if let Some(unknown) = entry.keys().find(|k| !FIELDS.contains(&k.as_str())) {
            bail!("motor {name:?}: unknown field {unknown:?} (LeRobot's are {})", FIELDS.join(", "));
        }
        let m = MotorCalibration {
            id: field(&name, entry, "id", 0, 253)? as u8,
            drive_mode: field(&name, entry, "drive_mode", 0, 1)? as u8,
            homing_offset: field(&name, entry, "homing_offset", i64::from(i32::MIN), i64::from(i32::MAX))? as i32,
            range_min: field(&name, entry, "range_min", 0, i64::from(i32::MAX))? as i32,
            range_max: field(&name, entry, "range_max", 0, i64::from(i32::MAX))? as i32,
        };
        motors.push((name, m));
    }
    let calibration = Calibration { motors };
    calibration.check()?;
    Ok(calibration)
}

/// Reads a LeRobot calibration file; errors name the file.
pub fn read(path: &Path) -> Result<Calibration> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse(&text).with_context(|| path.display().to_string())
}

/// The motors as one JSON object in their order.
struct InOrder<'a>(&'a Calibration);

impl Serialize for InOrder<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.motors.len()))?;
        for (name, m) in &self.0.motors {
            map.serialize_entry(name, m)?;
        }
        map.end()
    }
}

/// The file's text as LeRobot writes it: `json.dump(..., indent=4)`, the motors in order, each
/// entry's fields in LeRobot's order, no newline at the end.
pub fn to_text(calibration: &Calibration) -> String {
    let mut out = Vec::new();
    let formatter = serde_json::ser::PrettyFormatter::with_indent(b"    ");
    let mut serializer = serde_json::Serializer::with_formatter(&mut out, formatter);
    // Strings, integers and maps only: serialising them cannot fail.
    let _ = InOrder(calibration).serialize(&mut serializer);
    String::from_utf8(out).unwrap_or_default()
}

/// Where LeRobot keeps calibrations, from its environment variables (`env` looks one up).
pub fn calibration_dir(env: impl Fn(&str) -> Option<String>) -> Option<PathBuf> {
    if let Some(dir) = env("HF_LEROBOT_CALIBRATION").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(dir));
    }
    let hf_home = match env("HF_HOME").filter(|d| !d.is_empty()) {
        Some(home) => PathBuf::from(home),
        None => PathBuf::from(env("HOME").filter(|d| !d.is_empty())?).join(".cache").join("huggingface"),
    };
    Some(hf_home.join("lerobot").join("calibration"))
}

/// The file of robot `kind` (e.g. `so_follower`) with id `id` under `dir`.
pub fn robot_file(dir: &Path, kind: &str, id: &str) -> PathBuf {
    dir.join("robots").join(kind).join(format!("{id}.json"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An SO-101 follower's file as LeRobot writes it. The values are made up in the ranges a
    /// calibrated arm has (the wrist roll full-turn); the text is what Python 3's
    /// `json.dump(calibration, f, indent=4)` wrote for them, byte for byte.
    const SO101: &str = r#"{
    "shoulder_pan": {
        "id": 1,
        "drive_mode": 0,
        "homing_offset": -1470,
        "range_min": 758,
        "range_max": 3292
    },
    "shoulder_lift": {
        "id": 2,
        "drive_mode": 0,
        "homing_offset": 157,
        "range_min": 812,
        "range_max": 3313
    },
    "elbow_flex": {
        "id": 3,
        "drive_mode": 0,
        "homing_offset": 1007,
        "range_min": 893,
        "range_max": 3092
    },
    "wrist_flex": {
        "id": 4,
        "drive_mode": 0,
        "homing_offset": -1007,
        "range_min": 869,
        "range_max": 3261
    },
    "wrist_roll": {
        "id": 5,
        "drive_mode": 0,
        "homing_offset": -1838,
        "range_min": 0,
        "range_max": 4095
    },
    "gripper": {
        "id": 6,
        "drive_mode": 0,
        "homing_offset": 1160,
        "range_min": 2019,
        "range_max": 3367
    }
}"#;

    #[test]
    fn a_lerobot_file_reads_in_order_and_writes_back_byte_for_byte() {
        let c = parse(SO101).unwrap();
        let names: Vec<&str> = c.motors.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]);
        assert_eq!(
            *c.motor("shoulder_pan").unwrap(),
            MotorCalibration { id: 1, drive_mode: 0, homing_offset: -1470, range_min: 758, range_max: 3292 }
        );
        assert_eq!(c.by_id(6).unwrap().0, "gripper");
        assert_eq!(to_text(&c), SO101);
    }

    fn error(text: &str) -> String {
        format!("{:#}", parse(text).unwrap_err())
    }

    #[test]
    fn bad_files_are_one_line_naming_the_motor() {
        let one = |body: &str| format!("{{\"gripper\": {{{body}}}}}");
        let ok = "\"id\": 6, \"drive_mode\": 0, \"homing_offset\": 0, \"range_min\": 10, \"range_max\": 20";
        assert!(parse(&one(ok)).is_ok());
        for (body, needle) in [
            ("\"id\": 6, \"drive_mode\": 0, \"homing_offset\": 0, \"range_min\": 10", "no \"range_max\""),
            (&ok.replace("10", "20"), "a range of zero width"),
            (&ok.replace("\"id\": 6", "\"id\": 300"), "\"id\" 300 is outside 0..=253"),
            (&ok.replace("\"drive_mode\": 0", "\"drive_mode\": 2"), "\"drive_mode\" 2 is outside 0..=1"),
            (&ok.replace("\"homing_offset\": 0", "\"homing_offset\": 0.5"), "not an integer"),
            (&ok.replace("\"homing_offset\": 0", "\"homing_offset\": NaN"), "not a LeRobot calibration"),
            (&format!("{ok}, \"calib_mode\": 1"), "unknown field \"calib_mode\""),
        ] {
            let e = error(&one(body));
            assert!(e.contains(needle), "{body}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
        assert!(error("[1, 2]").contains("not a LeRobot calibration"));
        assert!(error("{}").contains("names no motor"));
        assert!(error("{\"a\": 3}").contains("not an object"));
        let twice = format!("{{\"a\": {{{ok}}}, \"b\": {{{ok}}}}}");
        assert!(error(&twice).contains("same name or id (6)"), "{}", error(&twice));
        let old = r#"{"motor_names": ["a"], "homing_offset": [0], "drive_mode": [0], "start_pos": [0],
            "end_pos": [1], "calib_mode": ["DEGREE"]}"#;
        assert!(error(old).contains("older calibration format"), "{}", error(old));
    }

    #[test]
    fn the_calibration_directory_follows_lerobots_variables() {
        let env = |vars: &'static [(&'static str, &'static str)]| {
            move |k: &str| vars.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        assert_eq!(calibration_dir(env(&[("HF_LEROBOT_CALIBRATION", "/c"), ("HF_HOME", "/h")])), Some("/c".into()));
        assert_eq!(calibration_dir(env(&[("HF_HOME", "/h")])), Some("/h/lerobot/calibration".into()));
        assert_eq!(
            calibration_dir(env(&[("HOME", "/home/me")])),
            Some("/home/me/.cache/huggingface/lerobot/calibration".into())
        );
        assert_eq!(calibration_dir(env(&[])), None);
        assert_eq!(
            robot_file(Path::new("/c"), "so_follower", "my_arm"),
            PathBuf::from("/c/robots/so_follower/my_arm.json")
        );
    }
}
