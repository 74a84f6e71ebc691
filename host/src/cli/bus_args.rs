//! Command-line names of the servo-bus protocols and models, shared by `armctl servo`,
//! `armctl sim servos` and `armctl bench bus`.

use clap::ValueEnum;
use firmware::bus::table::{Model, STS3215, XL330_M288, XL430_W250, XM430_W350};
use firmware::bus::Protocol;

/// The protocol on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProtocolArg {
    /// Dynamixel Protocol 2.0.
    Dxl2,
    /// Feetech SCS/STS.
    Sts,
}

impl From<ProtocolArg> for Protocol {
    fn from(p: ProtocolArg) -> Self {
        match p {
            ProtocolArg::Dxl2 => Protocol::Dxl2,
            ProtocolArg::Sts => Protocol::Feetech,
        }
    }
}

/// The servo model on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelArg {
    /// ROBOTIS XL430-W250 (Dynamixel).
    Xl430W250,
    /// ROBOTIS XM430-W350 (Dynamixel).
    Xm430W350,
    /// ROBOTIS XL330-M288 (Dynamixel).
    Xl330M288,
    /// Feetech STS3215.
    Sts3215,
}

impl ModelArg {
    /// The firmware's table of the model.
    pub fn model(self) -> &'static Model {
        match self {
            Self::Xl430W250 => &XL430_W250,
            Self::Xm430W350 => &XM430_W350,
            Self::Xl330M288 => &XL330_M288,
            Self::Sts3215 => &STS3215,
        }
    }
}

/// The model asked for, or the protocol's usual one (XL430-W250 on Dynamixel, STS3215 on
/// Feetech); an error line when the model speaks the other protocol.
pub fn model_for(protocol: Protocol, model: Option<ModelArg>) -> anyhow::Result<&'static Model> {
    let model = match (model, protocol) {
        (Some(m), _) => m.model(),
        (None, Protocol::Dxl2) => &XL430_W250,
        (None, Protocol::Feetech) => &STS3215,
    };
    if model.protocol != protocol {
        anyhow::bail!("--model {} speaks {}, not {}", model.name, model.protocol.name(), protocol.name());
    }
    Ok(model)
}
