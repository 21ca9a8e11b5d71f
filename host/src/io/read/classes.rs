//! Which LAS/LAZ points a read keeps, by their ASPRS classification and withheld flag. Survey
//! files classify their noise (7, low noise; 18, high noise, LAS 1.4) and flag points to leave
//! out (withheld); PDAL users expect neither in a product, so a read leaves both out unless
//! asked. Other formats carry no classes and keep every point.

use std::str::FromStr;

use serde::Serialize;

/// ASPRS low noise.
pub const LOW_NOISE: u8 = 7;
/// ASPRS high noise (LAS 1.4).
pub const HIGH_NOISE: u8 = 18;

/// The points of a classified file a read keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Classes {
    /// Every point but noise (classes 7 and 18) and withheld points: PDAL's usual
    /// `Classification![7:7], Classification![18:18]` with withheld points dropped.
    #[default]
    NotNoise,
    /// Every point, noise and withheld ones included.
    All,
    /// Only points of these classes (a bit per class 0..=255), withheld ones left out.
    Only([u64; 4]),
}

/// Why a point was left out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeftOut {
    Noise,
    Withheld,
    OtherClass,
}

/// How many points a read left out, and why.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClassDrops {
    /// Classified 7 or 18.
    pub noise: usize,
    /// Flagged withheld.
    pub withheld: usize,
    /// Of a class `--classes` did not name.
    pub other_classes: usize,
}

impl ClassDrops {
    pub fn note(&mut self, why: LeftOut) {
        match why {
            LeftOut::Noise => self.noise += 1,
            LeftOut::Withheld => self.withheld += 1,
            LeftOut::OtherClass => self.other_classes += 1,
        }
    }

    pub fn total(&self) -> usize {
        self.noise + self.withheld + self.other_classes
    }

    /// Another read's counts added to these (the scans of one registration file).
    pub fn add(&mut self, other: Self) {
        self.noise += other.noise;
        self.withheld += other.withheld;
        self.other_classes += other.other_classes;
    }
}

impl Classes {
    /// Whether a point of `class`, withheld or not, is kept; if not, why.
    pub fn keeps(self, class: u8, withheld: bool) -> Result<(), LeftOut> {
        match self {
            Self::All => Ok(()),
            _ if withheld => Err(LeftOut::Withheld),
            Self::NotNoise if class == LOW_NOISE || class == HIGH_NOISE => Err(LeftOut::Noise),
            Self::NotNoise => Ok(()),
            Self::Only(set) => {
                let word = set.get(usize::from(class / 64)).copied().unwrap_or(0);
                if word >> (class % 64) & 1 == 1 {
                    Ok(())
                } else {
                    Err(LeftOut::OtherClass)
                }
            }
        }
    }
}

impl FromStr for Classes {
    type Err = String;

    /// `not-noise` (the default), `all`, or classes separated by commas (`2,6`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "not-noise" => return Ok(Self::NotNoise),
            "all" => return Ok(Self::All),
            _ => {}
        }
        let mut set = [0u64; 4];
        for word in s.split(',') {
            let class: u8 = word.trim().parse().map_err(|_| {
                format!(
                    "'{}' is not an ASPRS class (0-255); --classes takes not-noise, all, or classes like 2,6",
                    word.trim()
                )
            })?;
            if let Some(bits) = set.get_mut(usize::from(class / 64)) {
                *bits |= 1 << (class % 64);
            }
        }
        Ok(Self::Only(set))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_leaves_out_noise_and_withheld_points_only() {
        let c = Classes::default();
        assert_eq!(c.keeps(2, false), Ok(()));
        assert_eq!(c.keeps(7, false), Err(LeftOut::Noise));
        assert_eq!(c.keeps(18, false), Err(LeftOut::Noise));
        assert_eq!(c.keeps(2, true), Err(LeftOut::Withheld));
        assert_eq!(Classes::All.keeps(7, true), Ok(()));
        let only: Classes = "2, 6,255".parse().expect("classes");
        assert_eq!(only.keeps(6, false), Ok(()));
        assert_eq!(only.keeps(255, false), Ok(()));
        assert_eq!(only.keeps(7, false), Err(LeftOut::OtherClass));
        assert!("2,x".parse::<Classes>().is_err());
        assert!("256".parse::<Classes>().is_err());
    }
}
