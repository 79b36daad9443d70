//! Module status words: the 32-bit CUBESTATE parameter and the 8-bit short state of motion replies.

use std::fmt;

/// Writes `A|B|0x..` for the named set bits of `bits`, plus any unnamed remainder in hex.
fn write_flags(f: &mut fmt::Formatter<'_>, bits: u32, names: &[(u32, &str)]) -> fmt::Result {
    let mut rest = bits;
    let mut first = true;
    let mut sep = |f: &mut fmt::Formatter<'_>| -> fmt::Result {
        if !std::mem::take(&mut first) {
            f.write_str("|")?;
        }
        Ok(())
    };
    for &(bit, name) in names {
        if bits & bit != 0 {
            sep(f)?;
            f.write_str(name)?;
            rest &= !bit;
        }
    }
    if rest != 0 {
        sep(f)?;
        write!(f, "{rest:#x}")?;
    }
    if bits == 0 {
        f.write_str("(none)")?;
    }
    Ok(())
}

/// The CUBESTATE parameter (0x27), a u32 of status flags.
///
/// ```text
///  bit        name              meaning
///  0x0000001  ERROR             an error occurred; needs RESET
///  0x0000002  HOME_OK           homing done, positions are valid
///  0x0000004  HALTED            module halted (HALT command or error)
///  0x0000008  POWERFAULT        power stage fault
///  0x0000010  TOW_ERROR         tow error: position lag beyond limit
///  0x0000020  COMM_ERROR        communication error
///  0x0000800  MOTION            module is moving
///  0x0008000  RAMP_END          ramp motion finished
///  0x2000000  BEYOND_HARD       beyond hard limit
///  0x4000000  BEYOND_SOFT       beyond soft limit
/// ```
/// Other bits are kept and shown in hex: we only name what PROTOCOLS.md lists.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct CubeState(pub u32);

impl CubeState {
    pub const ERROR: u32 = 0x1;
    pub const HOME_OK: u32 = 0x2;
    pub const HALTED: u32 = 0x4;
    pub const POWERFAULT: u32 = 0x8;
    pub const TOW_ERROR: u32 = 0x10;
    pub const COMM_ERROR: u32 = 0x20;
    pub const MOTION: u32 = 0x800;
    pub const RAMP_END: u32 = 0x8000;
    pub const BEYOND_HARD_LIMIT: u32 = 0x200_0000;
    pub const BEYOND_SOFT_LIMIT: u32 = 0x400_0000;

    const NAMES: [(u32, &'static str); 10] = [
        (Self::ERROR, "ERROR"),
        (Self::HOME_OK, "HOME_OK"),
        (Self::HALTED, "HALTED"),
        (Self::POWERFAULT, "POWERFAULT"),
        (Self::TOW_ERROR, "TOW_ERROR"),
        (Self::COMM_ERROR, "COMM_ERROR"),
        (Self::MOTION, "MOTION"),
        (Self::RAMP_END, "RAMP_END"),
        (Self::BEYOND_HARD_LIMIT, "BEYOND_HARD_LIMIT"),
        (Self::BEYOND_SOFT_LIMIT, "BEYOND_SOFT_LIMIT"),
    ];

    pub const fn bits(self) -> u32 {
        self.0
    }

    /// All bits of `flags` are set.
    pub const fn contains(self, flags: u32) -> bool {
        self.0 & flags == flags
    }

    pub const fn is_error(self) -> bool {
        self.contains(Self::ERROR)
    }

    pub const fn is_homed(self) -> bool {
        self.contains(Self::HOME_OK)
    }

    pub const fn is_moving(self) -> bool {
        self.contains(Self::MOTION)
    }

    /// A state the module must be RESET out of before it moves again (Player's rule: ERROR).
    /// Power, tow and limit faults set ERROR as well on real modules; we also treat them as
    /// faults on their own in case a firmware reports them without it.
    pub const fn is_fault(self) -> bool {
        self.0 & (Self::ERROR | Self::POWERFAULT | Self::TOW_ERROR | Self::BEYOND_HARD_LIMIT) != 0
    }
}

impl fmt::Display for CubeState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_flags(f, self.0, &Self::NAMES)
    }
}

impl fmt::Debug for CubeState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CubeState({:#x}: {self})", self.0)
    }
}

/// The one-byte state in the reply to a with-reply motion command (FRAMP_ACK, FSTEP_ACK, FVEL_ACK).
///
/// ```text
///  bit   name          meaning
///  0x01  ERROR         module in error (read CUBESTATE for details)
///  0x10  MOTION        moving
///  0x20  RAMP_END      ramp finished
///  0x40  IN_PROGRESS   motion command in progress
///  0x80  BUFFER_FULL   command buffer full
/// ```
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct ShortState(pub u8);

impl ShortState {
    pub const ERROR: u8 = 0x01;
    pub const MOTION: u8 = 0x10;
    pub const RAMP_END: u8 = 0x20;
    pub const IN_PROGRESS: u8 = 0x40;
    pub const BUFFER_FULL: u8 = 0x80;

    const NAMES: [(u32, &'static str); 5] = [
        (Self::ERROR as u32, "ERROR"),
        (Self::MOTION as u32, "MOTION"),
        (Self::RAMP_END as u32, "RAMP_END"),
        (Self::IN_PROGRESS as u32, "IN_PROGRESS"),
        (Self::BUFFER_FULL as u32, "BUFFER_FULL"),
    ];

    pub const fn bits(self) -> u8 {
        self.0
    }

    pub const fn contains(self, flags: u8) -> bool {
        self.0 & flags == flags
    }

    pub const fn is_error(self) -> bool {
        self.contains(Self::ERROR)
    }

    pub const fn is_moving(self) -> bool {
        self.contains(Self::MOTION)
    }
}

impl fmt::Display for ShortState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_flags(f, u32::from(self.0), &Self::NAMES)
    }
}

impl fmt::Debug for ShortState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ShortState({:#04x}: {self})", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_state_display_lists_set_flags_and_unknown_bits() {
        assert_eq!(CubeState(0).to_string(), "(none)");
        assert_eq!(CubeState(0x2).to_string(), "HOME_OK");
        assert_eq!(CubeState(0x8803).to_string(), "ERROR|HOME_OK|MOTION|RAMP_END");
        assert_eq!(
            CubeState(0x600_0000 | 0x40).to_string(),
            "BEYOND_HARD_LIMIT|BEYOND_SOFT_LIMIT|0x40"
        );
        assert!(CubeState(0x3).is_error() && CubeState(0x3).is_homed());
        assert!(!CubeState(0x2).is_fault());
        assert!(CubeState(0x8).is_fault());
    }

    #[test]
    fn short_state_display() {
        assert_eq!(ShortState(0x31).to_string(), "ERROR|MOTION|RAMP_END");
        assert_eq!(ShortState(0x02).to_string(), "0x2");
        assert!(ShortState(0x10).is_moving());
    }
}
