//! Cone colours as the interchange formats spell them.

use std::fmt;
use std::str::FromStr;

/// The colour class of a cone.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Color {
    /// Left track boundary.
    Blue,
    /// Right track boundary.
    Yellow,
    /// Small orange cone.
    Orange,
    /// Big orange cone (start/finish).
    BigOrange,
    /// The detector could not tell.
    Unknown,
}

impl Color {
    /// The colours a cone on a track can have (all but `Unknown`).
    pub const KNOWN: [Color; 4] = [Color::Blue, Color::Yellow, Color::Orange, Color::BigOrange];

    /// The name used in the log and map files.
    pub fn as_str(self) -> &'static str {
        match self {
            Color::Blue => "blue",
            Color::Yellow => "yellow",
            Color::Orange => "orange",
            Color::BigOrange => "big_orange",
            Color::Unknown => "unknown",
        }
    }

    /// Whether two detections could be the same cone: the same colour, or
    /// either unknown.
    pub fn compatible(self, other: Color) -> bool {
        self == other || self == Color::Unknown || other == Color::Unknown
    }

    /// Index 0..5, for vote counters.
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Color {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Color {
    type Err = String;
    /// Accepts the FORMAT.md names plus EPFL's `small_orange`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.trim() {
            "blue" => Color::Blue,
            "yellow" => Color::Yellow,
            "orange" | "small_orange" => Color::Orange,
            "big_orange" => Color::BigOrange,
            "unknown" => Color::Unknown,
            other => return Err(format!("unknown cone colour '{other}'")),
        })
    }
}
