//! Enums of the layers beneath on the command line: they know no clap (`armctl-arm` is its own
//! crate, `commands` and `motion` are front-end neutral), so each lists its names and help in a
//! `NAMES` table ([`Scalar::NAMES`], [`SolverName::NAMES`], [`Method::NAMES`], [`Ends::NAMES`],
//! [`Board::NAMES`], [`RootOffset::NAMES`], [`Timing::NAMES`]) and offers them to clap here.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

use crate::arm::dof::{Scalar, SolverName};
use crate::commands::footprint::Board;
use crate::motion::mocap::skeleton::RootOffset;
use crate::motion::mocap::timing::Timing;
use crate::motion::trajectory::{Ends, Method};

/// A value by one of the names of `names` (each `(name, value, help)`), as clap's `ValueEnum`
/// would offer it: the names and their help in `--help`, the names in the error for another.
pub fn named<T: Copy + Send + Sync + 'static>(
    names: &'static [(&'static str, T, &'static str)],
) -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(names.iter().map(|&(name, _, help)| PossibleValue::new(name).help(help))).map(
        move |name| names.iter().find(|(n, _, _)| *n == name).map(|&(_, value, _)| value).expect("a possible value"),
    )
}

/// `--scalar f32|f64`.
pub fn scalar() -> impl TypedValueParser<Value = Scalar> {
    named(&Scalar::NAMES)
}

/// `--solver auto|analytic|dls|...`.
pub fn solver() -> impl TypedValueParser<Value = SolverName> {
    PossibleValuesParser::new(
        SolverName::NAMES
            .map(|(name, _, aliases, help)| PossibleValue::new(name).aliases(aliases.iter().copied()).help(help)),
    )
    .map(|name| name.parse::<SolverName>().expect("one of the possible values"))
}

/// `armctl trajectory sample --method linear|catmull-rom|...`.
pub fn method() -> impl TypedValueParser<Value = Method> {
    named(&Method::NAMES)
}

/// `armctl trajectory sample --ends zero|natural`.
pub fn ends() -> impl TypedValueParser<Value = Ends> {
    named(&Ends::NAMES)
}

/// `armctl footprint --board mps2-an386|stm32f411`.
pub fn board() -> impl TypedValueParser<Value = Board> {
    named(&Board::NAMES)
}

/// `--root-offset add|ignore`.
pub fn root_offset() -> impl TypedValueParser<Value = RootOffset> {
    named(&RootOffset::NAMES)
}

/// `--timing fit|captured`.
pub fn timing() -> impl TypedValueParser<Value = Timing> {
    named(&Timing::NAMES)
}
