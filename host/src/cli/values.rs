//! Enums of the layers below on the command line: `armctl-arm` and `motion` know no clap, so their
//! names and help ([`Scalar::NAMES`], [`SolverName::NAMES`], [`RootOffset::NAMES`],
//! [`Timing::NAMES`]) are offered to clap here.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

use crate::arm::dof::{Scalar, SolverName};
use crate::motion::mocap::skeleton::RootOffset;
use crate::motion::mocap::timing::Timing;

/// `--scalar f32|f64`.
pub fn scalar() -> impl TypedValueParser<Value = Scalar> {
    PossibleValuesParser::new(Scalar::NAMES.map(|(name, _, help)| PossibleValue::new(name).help(help)))
        .map(|name| name.parse::<Scalar>().expect("one of the possible values"))
}

/// `--solver auto|analytic|dls|...`.
pub fn solver() -> impl TypedValueParser<Value = SolverName> {
    PossibleValuesParser::new(
        SolverName::NAMES
            .map(|(name, _, aliases, help)| PossibleValue::new(name).aliases(aliases.iter().copied()).help(help)),
    )
    .map(|name| name.parse::<SolverName>().expect("one of the possible values"))
}

/// `--root-offset add|ignore`.
pub fn root_offset() -> impl TypedValueParser<Value = RootOffset> {
    PossibleValuesParser::new(RootOffset::NAMES.map(|(name, _, help)| PossibleValue::new(name).help(help)))
        .map(|name| RootOffset::from_name(&name).expect("one of the possible values"))
}

/// `--timing fit|captured`.
pub fn timing() -> impl TypedValueParser<Value = Timing> {
    PossibleValuesParser::new(Timing::NAMES.map(|(name, _, help)| PossibleValue::new(name).help(help)))
        .map(|name| Timing::from_name(&name).expect("one of the possible values"))
}
