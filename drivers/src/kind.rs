//! The table of PTU kinds: every protocol the crate speaks, its name in files and on command
//! lines, its default line speed, how to open its driver, and which mock device stands in for it.
//!
//! The daemon's configuration, the `sqscan ptu` and `sqscan mock` commands and the mock rig all
//! name a PTU through [`PtuKind`], so a new protocol is a driver module, a mock module, and one
//! variant here (its row in [`PtuKind::info`] and its arms in [`PtuKind::start`],
//! [`PtuKind::mock`] and [`AnyPtu`]'s delegation). The mock keeps its own implementation of the
//! device side: driver and mock check each other.

use std::fmt;
use std::path::Path;
use std::str::FromStr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::mpsc::UnboundedSender;

use crate::Error;
use crate::flir::{FlirConfig, FlirPtu};
use crate::link::{Link, SerialLink, open_serial};
use crate::mock::{MockDevice, MockFlirConfig, MockFlirPtu, MockPowerCube, MockPowerCubeConfig};
use crate::powercube::{ModuleId, PowerCubeConfig, PowerCubePtu};
use crate::ptu::{AxisConfig, Goal, Limits, PanTilt, PositionSample, PtuState};

/// A pan-tilt unit protocol.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PtuKind {
    /// AMTEC/Schunk PowerCube modules over RS-232.
    PowerCube,
    /// FLIR / Directed Perception PTU-D46, ASCII commands.
    Flir,
}

/// One row of the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PtuKindInfo {
    /// The name in configuration files and on command lines.
    pub name: &'static str,
    /// The unit's name for people (status lines, log messages).
    pub model: &'static str,
    /// One line on what it is (command-line help).
    pub description: &'static str,
    /// Line speed when none is given (8N1, raw, always).
    pub default_baud: u32,
}

impl PtuKind {
    /// Every kind, in the order help texts list them.
    pub const ALL: [PtuKind; 2] = [PtuKind::PowerCube, PtuKind::Flir];

    /// This kind's row of the table.
    pub const fn info(self) -> PtuKindInfo {
        match self {
            PtuKind::PowerCube => PtuKindInfo {
                name: "powercube",
                model: "PowerCube",
                description: "AMTEC/Schunk PowerCube modules over RS-232",
                // Player's setting, and the modules' factory one.
                default_baud: 38_400,
            },
            PtuKind::Flir => PtuKindInfo {
                name: "flir",
                model: "PTU-D46",
                description: "FLIR / Directed Perception PTU-D46 (ASCII)",
                default_baud: 9_600,
            },
        }
    }

    pub const fn name(self) -> &'static str {
        self.info().name
    }

    pub const fn model(self) -> &'static str {
        self.info().model
    }

    pub const fn description(self) -> &'static str {
        self.info().description
    }

    pub const fn default_baud(self) -> u32 {
        self.info().default_baud
    }

    /// Opens the serial port at `path` (at `settings.baud`, else the kind's default) and starts
    /// the unit on it.
    pub async fn open(self, path: &Path, settings: &PtuSettings) -> Result<AnyPtu<SerialLink>, Error> {
        let link = open_serial(path, settings.baud.unwrap_or(self.default_baud()))?;
        self.start(link, settings).await
    }

    /// Starts the unit on any link (a serial port, a pty, an in-memory duplex): reads its limits
    /// and gets it ready, without homing it.
    pub async fn start<S: Link>(self, link: S, settings: &PtuSettings) -> Result<AnyPtu<S>, Error> {
        let baud = settings.baud.unwrap_or(self.default_baud());
        let (pan, tilt) = (settings.pan, settings.tilt);
        Ok(match self {
            PtuKind::PowerCube => {
                let d = PowerCubeConfig::default();
                let cfg = PowerCubeConfig {
                    pan_module: module_id("PowerCube pan module id", settings.pan_module, d.pan_module)?,
                    tilt_module: module_id("PowerCube tilt module id", settings.tilt_module, d.tilt_module)?,
                    baud,
                    pan,
                    tilt,
                    ..d
                };
                AnyPtu::PowerCube(PowerCubePtu::new(link, cfg).await?)
            }
            PtuKind::Flir => {
                let cfg = FlirConfig {
                    baud,
                    pan,
                    tilt,
                    ..FlirConfig::default()
                };
                AnyPtu::Flir(FlirPtu::new(link, cfg).await?)
            }
        })
    }

    /// A fresh mock unit of this kind (its own device-side implementation of the protocol), and
    /// a line describing it for people.
    pub fn mock(self) -> MockUnit {
        match self {
            PtuKind::PowerCube => {
                let cfg = MockPowerCubeConfig::default();
                let description = format!(
                    "mock PowerCube: pan module {}, tilt module {}",
                    cfg.pan.id.get(),
                    cfg.tilt.id.get()
                );
                MockUnit {
                    device: Arc::new(Mutex::new(MockPowerCube::new(cfg))),
                    description,
                }
            }
            PtuKind::Flir => {
                let cfg = MockFlirConfig::default();
                let description = format!(
                    "mock PTU-D46: pan [{}, {}] steps at {} arcsec/step, tilt [{}, {}] steps at {} arcsec/step",
                    cfg.pan.min_steps,
                    cfg.pan.max_steps,
                    cfg.pan.resolution_arcsec,
                    cfg.tilt.min_steps,
                    cfg.tilt.max_steps,
                    cfg.tilt.resolution_arcsec
                );
                MockUnit {
                    device: Arc::new(Mutex::new(MockFlirPtu::new(cfg))),
                    description,
                }
            }
        }
    }
}

impl fmt::Display for PtuKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A PTU protocol name that is not in the table.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown PTU protocol {given:?}: give {}", known_names())]
pub struct UnknownPtuKind {
    pub given: String,
}

fn known_names() -> String {
    let names: Vec<String> = PtuKind::ALL.iter().map(|k| format!("{:?}", k.name())).collect();
    names.join(" or ")
}

impl FromStr for PtuKind {
    type Err = UnknownPtuKind;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        PtuKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| UnknownPtuKind { given: s.to_owned() })
    }
}

/// What every kind is opened with; a field a kind has no use for is ignored.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PtuSettings {
    /// Line speed; `None`: the kind's [`default_baud`](PtuKind::default_baud).
    pub baud: Option<u32>,
    /// Device to joint angle, per axis (calibration).
    pub pan: AxisConfig,
    pub tilt: AxisConfig,
    /// PowerCube module ids (1 to 31); `None`: 12 for pan, 11 for tilt.
    pub pan_module: Option<u8>,
    pub tilt_module: Option<u8>,
}

fn module_id(quantity: &'static str, given: Option<u8>, default: ModuleId) -> Result<ModuleId, Error> {
    match given {
        None => Ok(default),
        Some(n) => ModuleId::new(n).ok_or(Error::OutOfRange {
            quantity,
            value: f64::from(n),
            min: 1.0,
            max: 31.0,
        }),
    }
}

/// A mock unit ready to serve on a [`MockPort`](crate::mock::MockPort).
pub struct MockUnit {
    pub device: Arc<Mutex<dyn MockDevice>>,
    /// E.g. "mock PowerCube: pan module 12, tilt module 11".
    pub description: String,
}

/// A driver of any kind in the table.
pub enum AnyPtu<S> {
    PowerCube(PowerCubePtu<S>),
    Flir(FlirPtu<S>),
}

impl<S> AnyPtu<S> {
    pub fn kind(&self) -> PtuKind {
        match self {
            AnyPtu::PowerCube(_) => PtuKind::PowerCube,
            AnyPtu::Flir(_) => PtuKind::Flir,
        }
    }
}

/// Every call goes to the driver of the unit's kind.
macro_rules! delegate {
    ($self:ident, $p:ident => $call:expr) => {
        match $self {
            AnyPtu::PowerCube($p) => $call,
            AnyPtu::Flir($p) => $call,
        }
    };
}

impl<S: Link> PanTilt for AnyPtu<S> {
    async fn home(&mut self) -> Result<PositionSample, Error> {
        delegate!(self, p => p.home().await)
    }

    async fn move_to(&mut self, goal: Goal) -> Result<(), Error> {
        delegate!(self, p => p.move_to(goal).await)
    }

    async fn position(&mut self) -> Result<PositionSample, Error> {
        delegate!(self, p => p.position().await)
    }

    async fn track(
        &mut self,
        samples: Option<&UnboundedSender<PositionSample>>,
        timeout: Duration,
    ) -> Result<PositionSample, Error> {
        delegate!(self, p => p.track(samples, timeout).await)
    }

    async fn halt(&mut self) -> Result<(), Error> {
        delegate!(self, p => p.halt().await)
    }

    async fn state(&mut self) -> Result<PtuState, Error> {
        delegate!(self, p => p.state().await)
    }

    fn limits(&self) -> Limits {
        delegate!(self, p => p.limits())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_known() {
        for k in PtuKind::ALL {
            assert_eq!(k.name().parse::<PtuKind>(), Ok(k));
            assert_eq!(k.to_string(), k.name());
        }
        let e = "visca".parse::<PtuKind>().unwrap_err().to_string();
        assert_eq!(e, r#"unknown PTU protocol "visca": give "powercube" or "flir""#);
    }

    #[test]
    fn default_bauds_are_the_drivers_defaults() {
        assert_eq!(PtuKind::PowerCube.default_baud(), PowerCubeConfig::default().baud);
        assert_eq!(PtuKind::Flir.default_baud(), FlirConfig::default().baud);
    }

    #[test]
    fn a_bad_module_id_names_the_axis() {
        let d = PowerCubeConfig::default().pan_module;
        let e = module_id("PowerCube pan module id", Some(40), d).unwrap_err();
        assert!(e.to_string().contains("pan module"), "{e}");
        assert_eq!(module_id("x", None, d).unwrap(), d);
    }
}
