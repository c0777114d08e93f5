//! How many ConvGRU updates (Note S10) a flow command runs: a fixed count, or `auto`: at most the
//! weights' own count, stopping once an update moves the flow less than
//! [`super::video::AUTO_STOP_PX`] on average.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::video::AUTO_STOP_PX;
use crate::error::{Error, Result};

/// The most updates any command runs.
pub const MAX_ITERS: usize = 256;

/// A count of updates, or `auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Iters {
    Fixed(usize),
    Auto,
}

impl Iters {
    /// The most updates to run (`auto`: the weights' own `weights_iters`) and the early stop's
    /// threshold in pixels (`auto` only).
    pub fn resolve(self, weights_iters: usize) -> (usize, Option<f32>) {
        match self {
            Self::Fixed(n) => (n, None),
            Self::Auto => (weights_iters, Some(AUTO_STOP_PX)),
        }
    }

    /// Refuses a fixed count outside 1..=256.
    pub fn check(self) -> Result<Self> {
        match self {
            Self::Fixed(n) if !(1..=MAX_ITERS).contains(&n) => Err(Error::invalid(
                "iters",
                format!("must be 1..={MAX_ITERS} or auto, got {n}"),
            )),
            _ => Ok(self),
        }
    }
}

impl FromStr for Iters {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        if s == "auto" {
            return Ok(Self::Auto);
        }
        let n: usize = s.parse().map_err(|_| {
            Error::invalid(
                "iters",
                format!("expected a count 1..={MAX_ITERS} or auto, got {s:?}"),
            )
        })?;
        Self::Fixed(n).check()
    }
}

impl fmt::Display for Iters {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Fixed(n) => write!(f, "{n}"),
            Self::Auto => f.write_str("auto"),
        }
    }
}

/// A number, or the string `"auto"`.
impl Serialize for Iters {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Self::Fixed(n) => s.serialize_u64(*n as u64),
            Self::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> Deserialize<'de> for Iters {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Count(usize),
            Word(String),
        }
        let parsed = match Raw::deserialize(d)? {
            Raw::Count(n) => Self::Fixed(n).check(),
            Raw::Word(w) => w.parse(),
        };
        parsed.map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_auto_parse_and_print_back() {
        assert_eq!("12".parse::<Iters>().ok(), Some(Iters::Fixed(12)));
        assert_eq!("auto".parse::<Iters>().ok(), Some(Iters::Auto));
        for bad in ["0", "257", "twelve", "-1", ""] {
            assert!(bad.parse::<Iters>().is_err(), "{bad:?} accepted");
        }
        assert_eq!(Iters::Auto.to_string(), "auto");
        assert_eq!(Iters::Fixed(4).resolve(12), (4, None));
        assert_eq!(Iters::Auto.resolve(12), (12, Some(AUTO_STOP_PX)));
    }

    #[test]
    fn json_takes_a_number_or_auto() {
        let n: Iters = serde_json::from_str("4").expect("a count");
        let a: Iters = serde_json::from_str("\"auto\"").expect("auto");
        assert_eq!((n, a), (Iters::Fixed(4), Iters::Auto));
        assert!(serde_json::from_str::<Iters>("0").is_err());
        assert!(serde_json::from_str::<Iters>("\"often\"").is_err());
        assert_eq!(
            serde_json::to_string(&Iters::Auto).ok().as_deref(),
            Some("\"auto\"")
        );
        assert_eq!(
            serde_json::to_string(&Iters::Fixed(7)).ok().as_deref(),
            Some("7")
        );
    }
}
