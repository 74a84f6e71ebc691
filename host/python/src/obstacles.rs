//! Obstacles as Python gives them: a dict as the view's API takes one (`{"shape": "box", "centre":
//! [...], "size": [...]}`), or a tuple of the shape's kind and its fields in order
//! (`("box", centre, size)`, `("sphere", centre, radius)`, `("capsule", a, b, radius)`,
//! `("table", height)`, `("plane", normal, offset)`), numpy arrays as lists. Each is read by
//! [`armctl::arm::collision::edit::obstacle_from_json`], so its checks and words are the view's;
//! a bad one raises `ValueError`, and nothing is sent.

use armctl::arm::collision::edit::obstacle_from_json;
use armctl::arm::collision::{CollisionSpec, TABLE};
use kinematics::collision::Shape;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::{Map, Value};

/// An obstacle: its name if it gives one, and its shape.
pub type Given = (Option<String>, Shape<f64>);

/// The fields of each kind, in a tuple's order.
const FIELDS: [(&str, &[&str]); 5] = [
    ("box", &["centre", "size"]),
    ("sphere", &["centre", "radius"]),
    ("capsule", &["a", "b", "radius"]),
    ("table", &["height"]),
    ("plane", &["normal", "offset"]),
];

fn bad(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A Python value as JSON: numbers, strings, booleans, None, lists, tuples, dicts, and anything
/// with numpy's `tolist`. NaN and the infinities, which JSON cannot spell, go as their names, so
/// that the reader refuses them by name.
fn value_of(obj: &Bound<'_, PyAny>) -> PyResult<Value> {
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if obj.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        return Ok(Value::from(obj.extract::<f64>()?));
    }
    if obj.is_instance_of::<PyFloat>() {
        let x: f64 = obj.extract()?;
        return Ok(match serde_json::Number::from_f64(x) {
            Some(n) => Value::Number(n),
            None => Value::String(format!("{x}")),
        });
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Value::String(obj.extract()?));
    }
    if let Ok(dict) = obj.cast::<PyDict>() {
        let mut map = Map::new();
        for (k, v) in dict.iter() {
            let key: String = k.extract().map_err(|_| bad(format!("obstacle: a key {k} is not a string")))?;
            map.insert(key, value_of(&v)?);
        }
        return Ok(Value::Object(map));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        return obj.try_iter()?.map(|item| value_of(&item?)).collect::<PyResult<Vec<_>>>().map(Value::Array);
    }
    if obj.hasattr("tolist")? {
        return value_of(&obj.call_method0("tolist")?);
    }
    // Numbers of other kinds (numpy's scalars) by their float value.
    match obj.extract::<f64>() {
        Ok(x) => value_of(&PyFloat::new(obj.py(), x).into_any()),
        Err(_) => Err(bad(format!("obstacle: {} is not a number, a string or a list", obj.repr()?))),
    }
}

/// One obstacle from a dict or a tuple; `ValueError` with the one line of the view's reader.
pub fn obstacle(obj: &Bound<'_, PyAny>) -> PyResult<Given> {
    let value = match value_of(obj)? {
        Value::Array(items) => {
            let kind = items.first().and_then(Value::as_str).ok_or_else(|| {
                bad("obstacle: a tuple starts with its shape: (\"box\", centre, size), (\"sphere\", centre, radius), ...")
            })?;
            let fields = FIELDS.iter().find(|(k, _)| *k == kind).map(|(_, f)| *f).ok_or_else(|| {
                let kinds: Vec<&str> = FIELDS.iter().map(|(k, _)| *k).collect();
                bad(format!("obstacle shape {kind:?}: one of {}", kinds.join(", ")))
            })?;
            let rest = &items[1..];
            // A table's height may be left out.
            if rest.len() != fields.len() && !(kind == "table" && rest.is_empty()) {
                return Err(bad(format!(
                    "obstacle ({kind:?}, {}): expected {} values after the shape, found {}",
                    fields.join(", "),
                    fields.len(),
                    rest.len()
                )));
            }
            let mut map = Map::new();
            map.insert("shape".into(), Value::String(kind.into()));
            for (name, v) in fields.iter().zip(rest) {
                map.insert((*name).into(), v.clone());
            }
            Value::Object(map)
        }
        other => other,
    };
    obstacle_from_json(&value).map_err(|e| bad(format!("{e:#}")))
}

/// `spec` without its table (`table=False`) and with `add`ed; `ValueError` for a name taken or
/// too many obstacles.
pub fn edited(mut spec: CollisionSpec, table: bool, remove: &[String], add: Vec<Given>) -> PyResult<CollisionSpec> {
    if !table && spec.obstacles.iter().any(|o| o.name == TABLE) {
        spec = spec.without(TABLE);
    }
    for name in remove {
        spec.remove_obstacle(name).map_err(|e| bad(format!("{e:#}")))?;
    }
    for (name, shape) in add {
        spec.add_obstacle(name.as_deref(), shape).map_err(|e| bad(format!("{e:#}")))?;
    }
    Ok(spec)
}
