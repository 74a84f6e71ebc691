//! Opening the link to a board (a serial port), to the simulated board (SIL) or to a firmware core
//! run on this PC against the servos of a USB adapter (`--bus`), with the handshake and, when
//! asked, the arm configuration.

use crate::sim::physics::ServoKind;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use firmware::bus::Protocol;
use firmware::link::message::Info;

use crate::arm::collision::obstacle::Surroundings;
use crate::arm::collision::ObstacleSpec;
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;
use crate::link::arm_config::CollisionCheck;
use crate::link::serial::open_error;
use crate::link::session::Session;
use crate::link::Transport;
use crate::runtime::gravity::{gravity_parts, Compensation, Gains};
use crate::runtime::pc::{Pc, PcOptions};
use crate::runtime::sil::{Sil, SilOptions};

/// The simulated arm of `--sim` when `--arm` is not given.
pub const DEFAULT_SIM_ARM: &str = "so101";
/// The baud rate of `--port` and `--bus` when `--baud` is not given.
pub const DEFAULT_BAUD: u32 = 1_000_000;

/// The arm of `--bus` when `--arm` is not given: the preset whose servos speak the protocol.
pub fn default_bus_arm(protocol: Protocol) -> &'static str {
    match protocol {
        Protocol::Feetech => "so101",
        Protocol::Dxl2 => "open-manipulator-x",
    }
}

/// A servo protocol by the name people give it: `sts` (Feetech) or `dxl2` (Dynamixel 2.0).
pub fn protocol_named(name: &str) -> Result<Protocol> {
    match name.to_ascii_lowercase().as_str() {
        "sts" => Ok(Protocol::Feetech),
        "dxl2" => Ok(Protocol::Dxl2),
        _ => bail!("protocol {name:?}: sts (Feetech) or dxl2 (Dynamixel 2.0)"),
    }
}

/// `arm` with the LeRobot calibration in `file`, if one is given: each servo's entry found by its
/// id. Errors name the file.
pub fn calibrated(mut arm: ArmSpec, file: Option<&std::path::Path>) -> Result<ArmSpec> {
    let Some(file) = file else { return Ok(arm) };
    let calibration = crate::arm::calibration::lerobot::read(file)?;
    let mut servos =
        servos_of(&arm).ok_or_else(|| anyhow::anyhow!("arm {} has no servo mapping to calibrate", arm.name))?;
    servos.calibrate(&calibration).map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
    arm.servos = Some(servos);
    Ok(arm)
}

/// Where the arm to drive is, as a person names it (the command line's `--port`, `--bus`,
/// `--protocol`, `--baud`, `--sim`, `--arm`, `--calibration`, `--object-mm`; Python's `Arm`'s
/// keywords): checked and turned into a [`Target`] by [`Place::target`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Place {
    /// A board running the firmware on this serial port.
    pub port: Option<String>,
    /// Servos on this USB adapter's port, driven by the core on this PC.
    pub bus: Option<String>,
    /// The servos' protocol, with `bus`.
    pub protocol: Option<Protocol>,
    /// The baud rate of `port` or `bus`.
    pub baud: Option<u32>,
    /// The simulated arm.
    pub sim: bool,
    /// The arm: a preset or an arm file.
    pub arm: Option<String>,
    /// A LeRobot calibration file, with `bus`.
    pub calibration: Option<PathBuf>,
    /// With `sim`: an object this wide (mm) between the jaws.
    pub object_mm: Option<f64>,
    /// With `sim`: the servos asked for (`None`: the default, ideal).
    pub servos: Option<ServoKind>,
    /// Obstacles added to the arm's collision geometry, the table taken away.
    pub surroundings: Surroundings,
    /// With `sim`: the firmware is sent the geometry with its check off (`--no-collision-check`),
    /// so that the simulated arm can be seen to run into what is in the way.
    pub no_collision_check: bool,
    /// With `sim`: obstacles only the simulator knows (`--hidden-obstacle`): the simulated links
    /// stop at them, the firmware is not told (something nobody declared on the table).
    pub hidden_obstacles: Vec<ObstacleSpec>,
    /// Gravity compensation (`--gravity-compensation on|off`; `None`: on with physical simulated
    /// servos, off elsewhere: ideal servos do not sag, and it has not run on a real arm yet).
    pub gravity: Option<bool>,
}

impl Place {
    /// The arm to configure on the firmware: the one named, else [`Place::default_arm`].
    pub fn arm_name(&self) -> Option<&str> {
        self.arm.as_deref().or_else(|| self.default_arm())
    }

    /// The arm of `--bus` and `--sim` when none is named (`None` for a board, which keeps the arm
    /// it runs).
    pub fn default_arm(&self) -> Option<&'static str> {
        match (&self.bus, self.protocol, self.sim) {
            (Some(_), Some(protocol), _) => Some(default_bus_arm(protocol)),
            (None, _, true) => Some(DEFAULT_SIM_ARM),
            _ => None,
        }
    }

    /// The board or simulation to connect to and the arm to configure on it
    /// ([`Place::target`], [`Place::arm_name`]).
    pub fn target_and_arm(&self) -> Result<(Target, Option<&str>)> {
        Ok((self.target()?, self.arm_name()))
    }

    /// The arm `name` (a preset or an arm file) with the surroundings applied.
    pub fn load(&self, name: &str) -> Result<ArmSpec> {
        ArmSpec::load(name, None)?.with_surroundings(&self.surroundings)
    }

    /// The gravity compensation this place asks for, the servos holding P gains as `gains` says.
    fn compensation(&self, gains: Gains) -> Result<Option<Compensation>> {
        let physical = match self.servos {
            Some(ServoKind::Physical(payload)) => Some(payload.map(|p| p.kg)),
            _ => None,
        };
        Ok(match (self.gravity, physical) {
            (Some(false), _) => None,
            (None, Some(payload_kg)) => Some(Compensation::by_default(gains, payload_kg)),
            (Some(true), Some(payload_kg)) => Some(Compensation { gains, payload_kg, asked: true }),
            (Some(true), None) if self.sim => bail!(
                "--gravity-compensation on needs servos that sag (--servos physical): ideal ones reach their goals \
                 exactly, and the offsets would lift the arm off them"
            ),
            (Some(true), None) => Some(Compensation { gains, payload_kg: None, asked: true }),
            (None, None) => None,
        })
    }

    /// The board or simulation to connect to; every option checked against the others.
    pub fn target(&self) -> Result<Target> {
        if self.no_collision_check && !self.sim {
            bail!("--no-collision-check is for the simulated arm only (--sim): a real arm is always checked");
        }
        if self.servos.is_some() && !self.sim {
            bail!("--servos and --payload-kg choose the simulated servos: they need --sim");
        }
        if !self.hidden_obstacles.is_empty() && !self.sim {
            bail!("--hidden-obstacle puts an obstacle in the simulated world only: it needs --sim");
        }
        if self.object_mm.is_some() && !self.sim {
            bail!("--object-mm puts an object between the simulated gripper's jaws: it needs --sim");
        }
        if let Some(path) = &self.bus {
            if self.port.is_some() || self.sim {
                bail!("--bus, --port and --sim exclude each other: give one");
            }
            let Some(protocol) = self.protocol else {
                bail!(
                    "--bus needs --protocol: sts (Feetech, SO-100/SO-101) or dxl2 (Dynamixel, Koch, OpenManipulator-X)"
                )
            };
            let arm = self.arm.as_deref().unwrap_or(default_bus_arm(protocol));
            let spec = calibrated(self.load(arm)?, self.calibration.as_deref())?;
            let options = PcOptions {
                path: path.clone(),
                protocol,
                // The arm file's rate unless --baud names one.
                baud: self.baud.or(spec.bus_baud()).unwrap_or(DEFAULT_BAUD),
                arm: spec,
                calibration_file: self.calibration.as_ref().map(|f| f.display().to_string()),
                monitor: None,
                // The core sets the servos up as it connects.
                gravity: self.compensation(Gains::SetUp)?,
            };
            return Ok(Target::Bus(Box::new(options)));
        }
        if self.protocol.is_some() {
            bail!("--protocol is the servo protocol of --bus, which is missing");
        }
        if self.calibration.is_some() {
            bail!("--calibration applies to --bus (the core on this PC) only for now");
        }
        match (&self.port, self.sim) {
            (Some(path), false) => {
                // The board's arm is sent as it is named unless the command line changes its
                // surroundings: then the arm, loaded here with them, is sent.
                let arm = match (&self.arm, self.surroundings.is_empty()) {
                    (_, true) => None,
                    (Some(arm), false) => Some(Box::new(self.load(arm)?)),
                    (None, false) => {
                        bail!("--obstacle and --no-table change the arm sent to the board: name it with --arm")
                    }
                };
                // A real arm's servos hold what `armctl servo setup` wrote.
                let gravity = self.compensation(Gains::SetUp)?;
                Ok(Target::Port { path: path.clone(), baud: self.baud.unwrap_or(DEFAULT_BAUD), arm, gravity })
            }
            (None, true) if self.baud.is_some() => bail!("--baud is the baud rate of --port; --sim has none"),
            (None, true) => {
                let arm = self.load(self.arm.as_deref().unwrap_or(DEFAULT_SIM_ARM))?;
                let collision_check = if self.no_collision_check { CollisionCheck::Off } else { CollisionCheck::On };
                // The simulated world: what the firmware is sent, and what is hidden from it.
                let hidden = Surroundings { obstacles: self.hidden_obstacles.clone(), no_table: false };
                let world = arm.clone().with_surroundings(&hidden).map_err(|e| hidden_error(&e))?;
                let options = SilOptions {
                    contact: crate::arm::collision::collision_of(&world),
                    object_mm: self.object_mm,
                    collision_check,
                    servos: self.servos.unwrap_or_default(),
                    // Nothing sets the simulated board's servos up: they hold the factory's gains.
                    gravity: self.compensation(Gains::Factory)?,
                    ..SilOptions::for_arm(arm)?
                };
                Ok(Target::Sim(Box::new(options)))
            }
            (Some(_), true) => bail!("--port and --sim exclude each other: give one"),
            (None, false) if self.baud.is_some() => {
                bail!("--baud is the baud rate of --port or --bus, which is missing")
            }
            (None, false) => bail!(
                "this command drives an arm: give --port PORT (a board running the firmware), --bus PORT --protocol \
                 sts|dxl2 (servos on a USB adapter) or --sim (the simulated arm) before it, e.g. `armctl --sim status`"
            ),
        }
    }
}

/// `--hidden-obstacle`'s error in its own words (the geometry's speak of `--obstacle`).
fn hidden_error(e: &anyhow::Error) -> anyhow::Error {
    anyhow!("--hidden-obstacle: {}", e.to_string().replace("--obstacle", "--obstacle and --hidden-obstacle"))
}

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
        /// Gravity compensation given to the firmware once connected.
        gravity: Option<Compensation>,
        /// The arm to send, loaded (`--obstacle` and `--no-table` applied); `None`: the one named
        /// at the handshake, or the board's.
        arm: Option<Box<ArmSpec>>,
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
                let (mut pc, servos) =
                    PcOptions::simulated(options.arm, Some(SIM_ADAPTER_LATENCY), options.servos, options.contact)?;
                // Asked for as for the simulated board, the gains the core sets up.
                pc.gravity = options.gravity.map(|c| Compensation { gains: Gains::SetUp, ..c });
                Ok((Target::Bus(Box::new(pc)), Some(servos)))
            }
            other => Ok((other, None)),
        }
    }
}

/// An open link after the handshake.
pub struct Connection {
    /// The session over the link.
    pub session: Session<Box<dyn Transport>>,
    /// The firmware's answer to the handshake (after any configuration).
    pub info: Info,
    /// The arm the firmware runs, for forward kinematics on the host.
    pub arm: ArmSpec,
    /// The core run on this PC, for `--bus` (dropped after the client, which ends it).
    pub pc: Option<Pc>,
}

impl Connection {
    /// The simulated board at the other end, when the link is one (SIL, `--sim`).
    pub fn sil(&mut self) -> Option<&mut Sil> {
        let transport: &mut dyn Transport = &mut **self.session.transport();
        transport.as_any_mut().downcast_mut()
    }

    /// Ends the link (for `--bus`, after the core has written what the last request asked for)
    /// and says on `err` what the core's control loop did.
    pub fn close(self, err: &mut dyn std::io::Write) -> Result<()> {
        let Connection { session, pc, .. } = self;
        drop(session);
        if let Some(pc) = pc {
            let shared = pc.shared();
            drop(pc);
            writeln!(err, "bus: {}", shared.summary())?;
        }
        Ok(())
    }
}

/// Sends `arm` to the firmware (joint by joint) and repeats the handshake.
fn configure<T: Transport>(session: &mut Session<T>, arm: &ArmSpec) -> Result<Info> {
    let servos = servos_of(arm).ok_or_else(|| {
        anyhow!(
            "arm {} has no servo mapping: add a [servos] table to its arm file (the presets so101 and \
             open-manipulator-x have one)",
            arm.name
        )
    })?;
    session.configure_arm(arm, &servos, 0).with_context(|| format!("configuring arm {}", arm.name))?;
    Ok(session.hello()?)
}

/// Opens `target`, shakes hands and makes sure the firmware runs an arm: `arm` if given (sent to
/// the board unless it already runs it), else the one it has. What connecting to `--bus` measured
/// and wrote is said on `err`.
pub fn open(target: Target, arm: Option<&str>, err: &mut dyn std::io::Write) -> Result<Connection> {
    let mut pc = None;
    // The arm --bus or --sim loaded (with a calibration, or its servos simulated), or --port's
    // with its surroundings: sent as it is.
    let loaded_arm;
    let mut check = CollisionCheck::On;
    let gravity = gravity_asked(&target)?;
    let transport: Box<dyn Transport> = match target {
        Target::Port { path, baud, arm: loaded, .. } => {
            let port = serialport::new(&path, baud).timeout(READ_TIMEOUT).open().map_err(|e| open_error(&path, e))?;
            loaded_arm = loaded.map(|arm| *arm);
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
            check = options.collision_check;
            loaded_arm = Some(options.arm);
            Box::new(sil)
        }
    };
    let mut conn = connect(transport, loaded_arm, arm, pc, check)?;
    if let Some((compensation, early)) = gravity {
        let parts = match early {
            Some(parts) => parts,
            None => gravity_parts(&conn.arm, &compensation)?,
        };
        conn.session.gravity(&parts).context("giving the firmware gravity compensation")?;
    }
    if let Some(sil) = conn.sil() {
        sil.settle_reads();
    }
    Ok(conn)
}

/// The gravity compensation `target` asks for, and its parts where the arm is known before
/// connecting: compensation asked of an arm that cannot have it (no masses) is refused before
/// anything starts. A board's arm is known once connected.
fn gravity_asked(
    target: &Target,
) -> Result<Option<(Compensation, Option<Vec<firmware::controller::gravity::GravityJoint>>)>> {
    let (compensation, arm) = match target {
        Target::Port { gravity, .. } => (*gravity, None),
        Target::Bus(options) => (options.gravity, Some(&options.arm)),
        Target::Sim(options) => (options.gravity, Some(&options.arm)),
    };
    let Some(compensation) = compensation else { return Ok(None) };
    let parts = arm.map(|arm| gravity_parts(arm, &compensation)).transpose()?;
    Ok(Some((compensation, parts)))
}

/// The link to a simulated board already made (the demo's, recording its ticks), with `arm` (the
/// one the board was made for) sent as it is.
pub fn open_sil(sil: Sil, arm: ArmSpec) -> Result<Connection> {
    connect(Box::new(sil), Some(arm), None, None, CollisionCheck::On)
}

/// Opens the link of board `index` of a group of simulated boards on one clock (a rig's arms in
/// SIL), with `arm` (the one the board was made for) sent as it is.
pub fn open_in_group(group: &crate::runtime::sil::group::SilGroup, index: usize, arm: ArmSpec) -> Result<Connection> {
    let member = group.member(index).ok_or_else(|| anyhow!("no simulated board {index} in the group"))?;
    connect(Box::new(member), Some(arm), None, None, CollisionCheck::On)
}

/// The handshake over `transport`, with `loaded_arm` sent as it is or else `arm` by name; then,
/// for a core on this PC, the wait until it has read every servo.
fn connect(
    transport: Box<dyn Transport>,
    loaded_arm: Option<ArmSpec>,
    arm: Option<&str>,
    pc: Option<Pc>,
    check: CollisionCheck,
) -> Result<Connection> {
    let mut session = Session::over(transport);
    session.set_collision_check(check);
    let (info, spec) = match loaded_arm {
        Some(spec) => handshake_with(&mut session, Some(spec))?,
        None => handshake(&mut session, arm)?,
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
    Ok(Connection { session, info, arm: spec, pc })
}

/// The handshake over an open link: makes sure the firmware runs `arm` if given, else any arm this
/// host knows; returns its info and description.
///
/// `arm` is sent when the board runs an arm of another name, or the built-in arm where `arm` differs
/// from it (a calibrated SO-101). It is not sent when the board already runs it, digest and all
/// ([`crate::link::arm_config::digest_of`]). A board running another arm of the same name (another
/// calibration, an edited file, sent by another host or by `armctl serve`) is not overwritten:
/// that is an error, which says what to do.
pub fn handshake<T: Transport>(session: &mut Session<T>, arm: Option<&str>) -> Result<(Info, ArmSpec)> {
    handshake_with(session, arm.map(|name| ArmSpec::load(name, None)).transpose()?)
}

/// A simulated board served with `--no-collision-check` runs `arm` with its check off (its
/// digest, `board_digest`, is that of `arm` with the check off): so does the host's check, as it
/// would on that board's own command line.
/// An arm without geometry has no check to turn off (its digest is the same either way), and the
/// session's own setting stands when the board runs the arm as the session would send it.
fn adopt_check_off<T: Transport>(session: &mut Session<T>, arm: &ArmSpec, board_digest: u32) -> Result<()> {
    let Some(servos) = servos_of(arm) else { return Ok(()) };
    if crate::arm::collision::collision_of(arm).is_none() {
        return Ok(());
    }
    let digest = |check| crate::link::arm_config::arm_digest_checked(arm, &servos, check);
    if digest(session.collision_check())? != board_digest && digest(CollisionCheck::Off)? == board_digest {
        session.set_collision_check(CollisionCheck::Off);
    }
    Ok(())
}

/// [`handshake`] with the arm already loaded.
pub fn handshake_with<T: Transport>(session: &mut Session<T>, arm: Option<ArmSpec>) -> Result<(Info, ArmSpec)> {
    let mut info = session.hello().context("handshake with the firmware")?;
    let spec = match arm {
        Some(spec) => {
            if info.arm_name.as_str() != spec.name {
                info = configure(session, &spec)?;
            } else if let Some(servos) = servos_of(&spec) {
                adopt_check_off(session, &spec, info.arm_digest)?;
                let check = session.collision_check();
                let digest = crate::link::arm_config::arm_digest_checked(&spec, &servos, check)?;
                if info.arm_digest == firmware::builtin::DIGEST && digest != info.arm_digest {
                    // The default the board starts with gives way to the arm the host names.
                    info = configure(session, &spec)?;
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
        None => {
            let spec = ArmSpec::load(info.arm_name.as_str(), None).with_context(|| {
                format!("the board runs arm {}, which this host does not know; pass --arm", info.arm_name)
            })?;
            adopt_check_off(session, &spec, info.arm_digest)?;
            spec
        }
    };
    if usize::from(info.joints) != spec.dof() {
        bail!("the firmware drives {} joints, arm {} has {}", info.joints, spec.name, spec.dof());
    }
    Ok((info, spec))
}
