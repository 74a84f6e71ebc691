//! The JSON API's requests, checked like any host message before anything moves: bad JSON, a
//! missing field, a string where a number goes, a value out of its range. Each problem is an
//! [`ApiError`] with the HTTP status and one line in words.

use kinematics::collision::Shape;
use serde_json::Value;

use crate::arm::collision::edit::obstacle_from_json;

/// The largest request body: a keyframe file of some 50,000 lines.
pub const MAX_BODY: usize = 4 << 20;

/// A refused request: its HTTP status and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiError {
    /// 400 bad input, 404 unknown path, 405 wrong method, 409 conflicts with what the arm does,
    /// 413 too large, 422 refused by the firmware or unreachable, 503 the firmware is not answering.
    pub status: u16,
    /// One line.
    pub message: String,
    /// More fields for the error's body (the closest pose of an unreachable target).
    pub detail: Option<Value>,
}

impl ApiError {
    /// A 400 with this message.
    pub fn bad(message: impl Into<String>) -> Self {
        Self::new(400, message)
    }

    /// An error of another status.
    pub fn new(status: u16, message: impl Into<String>) -> Self {
        Self { status, message: message.into(), detail: None }
    }

    /// The body: `{"error": message}` and the detail's fields.
    pub fn body(&self) -> Value {
        let mut body = serde_json::json!({"error": self.message});
        if let (Some(Value::Object(extra)), Value::Object(map)) = (&self.detail, &mut body) {
            map.extend(extra.clone());
        }
        body
    }
}

/// Checked requests.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// Move every joint (values checked against the arm by the arm loop).
    Joints {
        /// One value per joint (rad or m).
        q: Vec<f64>,
        /// The fastest joint's speed (rad/s); `None` for as fast as the limits allow.
        speed: Option<f64>,
    },
    /// Preview a target by IK, and with `go` send it to the firmware.
    Target {
        /// Where (m).
        position: [f64; 3],
        /// The tool's orientation, w first, normalised.
        orientation: Option<[f64; 4]>,
        /// Send it to the firmware, not only preview it.
        go: bool,
    },
    /// Decelerate and hold; stop a playing file.
    Stop,
    /// Torque on or off.
    Torque(bool),
    /// The gripper's opening.
    Gripper(f64),
    /// Play a keyframe file's text.
    Play {
        /// The file's name, for messages.
        name: String,
        /// Its text.
        csv: String,
    },
    /// The collision geometry, for drawing (`GET /api/collision`).
    Collision,
    /// Obstacles removed by name, then added (each checked, the names its own or none): all or
    /// nothing, for the commands that follow.
    Obstacles {
        /// Names of obstacles to remove.
        remove: Vec<String>,
        /// Obstacles to add: a name (or `None` for one after its kind) and a shape in the base frame.
        add: Vec<(Option<String>, Shape<f64>)>,
    },
}

/// Parses a body as a JSON object.
fn object(body: &[u8]) -> Result<serde_json::Map<String, Value>, ApiError> {
    if body.len() > MAX_BODY {
        return Err(ApiError::new(413, format!("the body is {} bytes, more than {MAX_BODY}", body.len())));
    }
    match serde_json::from_slice::<Value>(body) {
        Ok(Value::Object(map)) => Ok(map),
        Ok(other) => Err(ApiError::bad(format!("the body must be a JSON object, not {}", kind(&other)))),
        Err(e) => Err(ApiError::bad(format!("bad JSON: {e}"))),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// A finite number.
fn number(v: &Value, what: &str) -> Result<f64, ApiError> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        Some(x) => Err(ApiError::bad(format!("{what}: {x} is not a finite number"))),
        // A number beyond f64 (read as such where serde_json keeps numbers as text).
        None if v.is_number() => Err(ApiError::bad(format!("{what}: {v} is not a finite number"))),
        None => Err(ApiError::bad(format!("{what}: expected a number, found {}", kind(v)))),
    }
}

/// An array of finite numbers, of length `len` if given.
fn numbers(v: &Value, what: &str, len: Option<usize>) -> Result<Vec<f64>, ApiError> {
    let items = v.as_array().ok_or_else(|| ApiError::bad(format!("{what}: expected an array, found {}", kind(v))))?;
    if let Some(n) = len.filter(|&n| n != items.len()) {
        return Err(ApiError::bad(format!("{what}: expected {n} numbers, found {}", items.len())));
    }
    items.iter().enumerate().map(|(i, x)| number(x, &format!("{what}[{i}]"))).collect()
}

fn field<'a>(map: &'a serde_json::Map<String, Value>, name: &str) -> Result<&'a Value, ApiError> {
    map.get(name).ok_or_else(|| ApiError::bad(format!("missing field \"{name}\"")))
}

fn refuse_unknown(map: &serde_json::Map<String, Value>, known: &[&str]) -> Result<(), ApiError> {
    match map.keys().find(|k| !known.contains(&k.as_str())) {
        Some(k) => Err(ApiError::bad(format!("unknown field \"{k}\" (this request takes {})", known.join(", ")))),
        None => Ok(()),
    }
}

fn boolean(v: &Value, what: &str) -> Result<bool, ApiError> {
    v.as_bool().ok_or_else(|| ApiError::bad(format!("{what}: expected true or false, found {}", kind(v))))
}

/// The endpoints of `POST /api/<endpoint>` (`/api/arm/NAME/<endpoint>` in a rig's view).
pub const ENDPOINTS: [&str; 7] = ["joints", "target", "stop", "torque", "gripper", "play", "obstacles"];

/// Parses the body of `POST /api/<endpoint>`.
pub fn parse(endpoint: &str, body: &[u8]) -> Result<Request, ApiError> {
    let map = object(body)?;
    match endpoint {
        "joints" => {
            refuse_unknown(&map, &["q", "speed"])?;
            let q = numbers(field(&map, "q")?, "q", None)?;
            let speed = match map.get("speed") {
                None => None,
                Some(v) => {
                    let s = number(v, "speed")?;
                    let max = f64::from(firmware::link::message::MAX_SPEED);
                    if !(s > 0.0 && s <= max) {
                        return Err(ApiError::bad(format!("speed: {s} rad/s must be above 0 and at most {max}")));
                    }
                    Some(s)
                }
            };
            Ok(Request::Joints { q, speed })
        }
        "target" => {
            refuse_unknown(&map, &["position", "orientation", "go"])?;
            let p = numbers(field(&map, "position")?, "position", Some(3))?;
            let reach = f64::from(firmware::link::message::MAX_REACH);
            if let Some(x) = p.iter().find(|x| x.abs() > reach) {
                return Err(ApiError::bad(format!("position: {x} m is more than {reach} m from the base")));
            }
            let orientation = match map.get("orientation") {
                None | Some(Value::Null) => None,
                Some(v) => {
                    let q = numbers(v, "orientation", Some(4))?;
                    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if (norm - 1.0).abs() > crate::arm::dof::QUATERNION_NORM_TOLERANCE {
                        return Err(ApiError::bad(format!(
                            "orientation: w,x,y,z must be a unit quaternion; its norm is {norm:.6}"
                        )));
                    }
                    Some([q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm])
                }
            };
            let go = map.get("go").map(|v| boolean(v, "go")).transpose()?.unwrap_or(false);
            Ok(Request::Target { position: [p[0], p[1], p[2]], orientation, go })
        }
        "stop" => {
            refuse_unknown(&map, &[])?;
            Ok(Request::Stop)
        }
        "torque" => {
            refuse_unknown(&map, &["on"])?;
            Ok(Request::Torque(boolean(field(&map, "on")?, "on")?))
        }
        "gripper" => {
            refuse_unknown(&map, &["percent"])?;
            let p = number(field(&map, "percent")?, "percent")?;
            if !(0.0..=100.0).contains(&p) {
                return Err(ApiError::bad(format!("percent: {p} must be within 0 (closed) and 100 (open)")));
            }
            Ok(Request::Gripper(p))
        }
        "play" => {
            refuse_unknown(&map, &["name", "csv"])?;
            let csv = field(&map, "csv")?
                .as_str()
                .ok_or_else(|| ApiError::bad("csv: expected the keyframe file's text as a string"))?
                .to_string();
            let name = match map.get("name") {
                None => "keyframes.csv".to_string(),
                Some(v) => v.as_str().ok_or_else(|| ApiError::bad("name: expected a string"))?.to_string(),
            };
            Ok(Request::Play { name, csv })
        }
        "obstacles" => {
            refuse_unknown(&map, &["add", "remove"])?;
            let list = |name: &str| match map.get(name) {
                None => Ok(Vec::new()),
                Some(Value::Array(items)) => Ok(items.clone()),
                Some(v) => Err(ApiError::bad(format!("{name}: expected an array, found {}", kind(v)))),
            };
            let remove = list("remove")?
                .iter()
                .map(|v| v.as_str().map(str::to_string).ok_or_else(|| ApiError::bad("remove: expected obstacle names")))
                .collect::<Result<Vec<_>, _>>()?;
            let add = list("add")?
                .iter()
                .enumerate()
                .map(|(i, v)| obstacle_from_json(v).map_err(|e| ApiError::bad(format!("add[{i}]: {e:#}"))))
                .collect::<Result<Vec<_>, _>>()?;
            if remove.is_empty() && add.is_empty() {
                return Err(ApiError::bad("nothing to do: give \"add\" (obstacles) or \"remove\" (names), or both"));
            }
            Ok(Request::Obstacles { remove, add })
        }
        other => Err(ApiError::new(404, format!("no endpoint POST /api/{other}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(endpoint: &str, body: &str) -> ApiError {
        parse(endpoint, body.as_bytes()).unwrap_err()
    }

    #[test]
    fn reads_each_request() {
        assert_eq!(
            parse("joints", br#"{"q": [0.1, -0.2]}"#).unwrap(),
            Request::Joints { q: vec![0.1, -0.2], speed: None }
        );
        assert_eq!(
            parse("target", br#"{"position": [0.2, 0, 0.1], "go": true}"#).unwrap(),
            Request::Target { position: [0.2, 0.0, 0.1], orientation: None, go: true }
        );
        assert_eq!(parse("torque", br#"{"on": false}"#).unwrap(), Request::Torque(false));
        assert_eq!(parse("stop", b"{}").unwrap(), Request::Stop);
        assert_eq!(parse("gripper", br#"{"percent": 40}"#).unwrap(), Request::Gripper(40.0));
        assert_eq!(
            parse("play", br#"{"name": "a.csv", "csv": "t,q1\n0,0\n"}"#).unwrap(),
            Request::Play { name: "a.csv".into(), csv: "t,q1\n0,0\n".into() }
        );
        let Request::Obstacles { remove, add } = parse(
            "obstacles",
            br#"{"remove": ["table"], "add": [{"shape": "sphere", "centre": [0.2, 0, 0.1], "radius": 0.03}]}"#,
        )
        .unwrap() else {
            panic!("obstacles")
        };
        assert_eq!(remove, ["table"]);
        assert_eq!(add.len(), 1);
    }

    #[test]
    fn refuses_bad_input_with_the_reason() {
        assert!(err("joints", "{\"q\": [0.1,").message.starts_with("bad JSON"));
        assert!(err("joints", r#"{"q": [NaN]}"#).message.starts_with("bad JSON"));
        assert_eq!(err("joints", r#"{"q": ["0.1"]}"#).message, "q[0]: expected a number, found a string");
        assert_eq!(err("joints", r#"{"q": 3}"#).message, "q: expected an array, found a number");
        assert_eq!(err("joints", "[1]").message, "the body must be a JSON object, not an array");
        assert_eq!(err("joints", "{}").message, "missing field \"q\"");
        assert_eq!(err("joints", r#"{"q": [0], "speed": 0}"#).status, 400);
        // Out of range for JSON's reader, or read as infinity where a crate of the workspace turns
        // on serde_json's arbitrary precision: refused either way.
        let huge = err("joints", r#"{"q": [1e999]}"#);
        assert!(huge.message.starts_with("bad JSON") || huge.message.contains("not a finite number"), "{huge:?}");
        assert_eq!(err("target", r#"{"position": [0, 0]}"#).message, "position: expected 3 numbers, found 2");
        assert_eq!(err("target", r#"{"position": [99, 0, 0]}"#).status, 400);
        assert!(err("target", r#"{"position": [0.2, 0, 0.1], "orientation": [1, 1, 0, 0]}"#)
            .message
            .contains("unit quaternion"));
        assert_eq!(err("torque", r#"{"on": "yes"}"#).message, "on: expected true or false, found a string");
        assert_eq!(err("gripper", r#"{"percent": 101}"#).status, 400);
        assert!(err("stop", r#"{"now": true}"#).message.starts_with("unknown field \"now\""));
        assert_eq!(err("fly", "{}").status, 404);
        let bad_box = r#"{"add": [{"shape": "box", "centre": [0.2, 0, 0], "size": [0.1, 0, 0.1]}]}"#;
        assert_eq!(
            err("obstacles", bad_box).message,
            "add[0]: obstacle box: size[1]: 0 m is not a size: it must be above 0"
        );
        assert_eq!(err("obstacles", "{}").status, 400);
        assert_eq!(err("obstacles", r#"{"remove": [1]}"#).message, "remove: expected obstacle names");
        let huge = format!("{{\"csv\": \"{}\"}}", "x".repeat(MAX_BODY));
        assert_eq!(err("play", &huge).status, 413);
    }
}
