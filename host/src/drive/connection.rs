//! Opening the link to a board (a serial port), to the simulated board (SIL) or to a firmware core
//! run on this PC against the servos of a USB adapter (`--bus`), with the handshake and, when
//! asked, the arm configuration.

use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use firmware::link::message::Info;

use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;
use crate::link::arm_config::configure_messages;
use crate::link::client::{LinkClient, LinkConfig};
use crate::link::serial::open_error;
use crate::link::Transport;
use crate::places::pc::{Pc, PcOptions};
use crate::places::sil::{Sil, SilOptions};

/// How long the PC-hosted core may take, once it has its arm, to read every servo and its torque.
const CORE_READY_TIMEOUT: Duration = Duration::from_secs(2);

pub use crate::link::READ_TIMEOUT;

/// Where the firmware runs.
pub enum Target {
    /// A board on a serial port.
    Port {
        /// Its path (`/dev/ttyACM0`, `COM3`).
        path: String,
        /// Baud rate (ignored by USB CDC boards).
        baud: u32,
    },
    /// The firmware core simulated in this process.
    Sim(Box<SilOptions>),
    /// The firmware core run in this process against real servos on a USB adapter.
    Bus(Box<PcOptions>),
}

/// The latency timer of the simulated USB adapter of [`Target::in_real_time`].
pub const SIM_ADAPTER_LATENCY: Duration = Duration::from_millis(1);

impl Target {
    /// The target for a loop that runs in real time (teleoperation, the browser view, a stream of
    /// actions from Python): `Sim` becomes the core on this PC in real time against simulated
    /// servos on a pseudo-terminal (as `armctl serve --sim`), with a USB adapter's 1 ms latency,
    /// returned with it for the safety monitor's report; the virtual clock of the drive commands'
    /// `--sim` would not pace such a loop. Other targets are returned as they are.
    pub fn in_real_time(self) -> Result<(Target, Option<crate::sim::PtyServer>)> {
        match self {
            Target::Sim(options) => {
                let (options, servos) = PcOptions::simulated(options.arm, Some(SIM_ADAPTER_LATENCY))?;
                Ok((Target::Bus(Box::new(options)), Some(servos)))
            }
            other => Ok((other, None)),
        }
    }
}

/// An open link after the handshake.
pub struct Connection {
    /// The link client.
    pub client: LinkClient<Box<dyn Transport>>,
    /// The firmware's answer to the handshake (after any configuration).
    pub info: Info,
    /// The arm the firmware runs, for forward kinematics on the host.
    pub arm: ArmSpec,
    /// The core run on this PC, for `--bus` (dropped after the client, which ends it).
    pub pc: Option<Pc>,
}

impl Connection {
    /// Ends the link (for `--bus`, after the core has written what the last request asked for)
    /// and says on `err` what the core's control loop did.
    pub fn close(self, err: &mut dyn std::io::Write) -> Result<()> {
        let Connection { client, pc, .. } = self;
        drop(client);
        if let Some(pc) = pc {
            let shared = pc.shared();
            drop(pc);
            writeln!(err, "bus: {}", shared.summary())?;
        }
        Ok(())
    }
}

/// Sends `arm` to the firmware (joint by joint) and repeats the handshake.
fn configure<T: Transport>(client: &mut LinkClient<T>, arm: &ArmSpec) -> Result<Info> {
    let servos = servos_of(arm).ok_or_else(|| {
        anyhow!(
            "arm {} has no servo mapping: add a [servos] table to its arm file (the presets so101 and \
             open-manipulator-x have one)",
            arm.name
        )
    })?;
    for message in configure_messages(arm, &servos)? {
        client.request(&message).with_context(|| format!("configuring arm {}", arm.name))?;
    }
    Ok(client.hello()?)
}

/// Opens `target`, shakes hands and makes sure the firmware runs an arm: `arm` if given (sent to
/// the board unless it already runs it), else the one it has. What connecting to `--bus` measured
/// and wrote is said on `err`.
pub fn open(target: Target, arm: Option<&str>, err: &mut dyn std::io::Write) -> Result<Connection> {
    let mut pc = None;
    // The arm --bus or --sim loaded (with a calibration, or its servos simulated): sent as it is.
    let mut loaded_arm = None;
    let transport: Box<dyn Transport> = match target {
        Target::Port { path, baud } => {
            let port = serialport::new(&path, baud).timeout(READ_TIMEOUT).open().map_err(|e| open_error(&path, e))?;
            Box::new(port)
        }
        Target::Bus(options) => {
            let mut core = Pc::start(&options, true, err)?;
            // Sent with the port's rate, which the core cannot change.
            loaded_arm = Some(options.arm.at_baud(options.baud));
            let link = core.take_link().ok_or_else(|| anyhow!("the core's link was taken"))?;
            pc = Some(core);
            Box::new(link)
        }
        Target::Sim(mut options) => {
            options.read_timeout_ms = READ_TIMEOUT.as_millis() as u64;
            let sil = Sil::new(&options)?;
            loaded_arm = Some(options.arm);
            Box::new(sil)
        }
    };
    connect(transport, loaded_arm, arm, pc)
}

/// Opens the link of board `index` of a group of simulated boards on one clock (a rig's arms in
/// SIL), with `arm` (the one the board was made for) sent as it is.
pub fn open_in_group(group: &crate::places::sil::group::SilGroup, index: usize, arm: ArmSpec) -> Result<Connection> {
    let member = group.member(index).ok_or_else(|| anyhow!("no simulated board {index} in the group"))?;
    connect(Box::new(member), Some(arm), None, None)
}

/// The handshake over `transport`, with `loaded_arm` sent as it is or else `arm` by name; then,
/// for a core on this PC, the wait until it has read every servo.
fn connect(
    transport: Box<dyn Transport>,
    loaded_arm: Option<ArmSpec>,
    arm: Option<&str>,
    pc: Option<Pc>,
) -> Result<Connection> {
    let mut client = LinkClient::new(transport, LinkConfig::default());
    let (info, spec) = match loaded_arm {
        Some(spec) => handshake_with(&mut client, Some(spec))?,
        None => handshake(&mut client, arm)?,
    };
    if let Some(core) = &pc {
        // Until every servo and its torque are read, the status would call a torqued arm limp.
        let shared = core.shared();
        let started = std::time::Instant::now();
        while !shared.ready() {
            if started.elapsed() > CORE_READY_TIMEOUT || core.is_finished() {
                bail!("the firmware core did not read every servo within {} s", CORE_READY_TIMEOUT.as_secs());
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    Ok(Connection { client, info, arm: spec, pc })
}

/// The handshake over an open link: makes sure the firmware runs `arm` if given, else any arm this
/// host knows; returns its info and description.
///
/// `arm` is sent when the board runs an arm of another name, or the built-in arm where `arm` differs
/// from it (a calibrated SO-101). It is not sent when the board already runs it, digest and all
/// ([`crate::link::arm_config::digest_of`]). A board running another arm of the same name (another
/// calibration, an edited file, sent by another host or by `armctl serve`) is not overwritten:
/// that is an error, which says what to do.
pub fn handshake<T: Transport>(client: &mut LinkClient<T>, arm: Option<&str>) -> Result<(Info, ArmSpec)> {
    handshake_with(client, arm.map(|name| ArmSpec::load(name, None)).transpose()?)
}

/// [`handshake`] with the arm already loaded.
pub fn handshake_with<T: Transport>(client: &mut LinkClient<T>, arm: Option<ArmSpec>) -> Result<(Info, ArmSpec)> {
    let mut info = client.hello().context("handshake with the firmware")?;
    let spec = match arm {
        Some(spec) => {
            if info.arm_name.as_str() != spec.name {
                info = configure(client, &spec)?;
            } else if let Some(servos) = servos_of(&spec) {
                let digest = crate::link::arm_config::arm_digest(&spec, &servos)?;
                if info.arm_digest == firmware::builtin::DIGEST && digest != info.arm_digest {
                    // The default the board starts with gives way to the arm the host names.
                    info = configure(client, &spec)?;
                } else if digest != info.arm_digest {
                    bail!(
                        "the board runs another arm named {} (another calibration or an edited file): not replaced; \
                         leave out --arm to drive the board's, or give this arm a name of its own to send it",
                        spec.name
                    );
                }
            }
            spec
        }
        None if info.arm_name.is_empty() => bail!("the board has no arm configured: pass --arm"),
        None => ArmSpec::load(info.arm_name.as_str(), None).with_context(|| {
            format!("the board runs arm {}, which this host does not know; pass --arm", info.arm_name)
        })?,
    };
    if usize::from(info.joints) != spec.dof() {
        bail!("the firmware drives {} joints, arm {} has {}", info.joints, spec.name, spec.dof());
    }
    Ok((info, spec))
}
