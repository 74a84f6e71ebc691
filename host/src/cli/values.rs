//! The arm crate's enums on the command line: `armctl-arm` knows no clap, so their names and help
//! ([`Scalar::NAMES`], [`SolverName::NAMES`]) are offered to clap here.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

use crate::arm::dof::{Scalar, SolverName};

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
