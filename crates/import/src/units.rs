//! The units a map may name, per quantity, and their factors to the dataset's unit.

/// What a column measures; fixes the dataset unit it is converted to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Gyro rate, to rad/s.
    AngularRate,
    /// Magnetic field, to nT.
    MagneticField,
    /// Photodiode output, to V.
    Voltage,
    /// Position, to km.
    Length,
    /// Temperature, to degrees Celsius.
    Temperature,
    /// Electric current, to amperes.
    Current,
}

impl Quantity {
    /// The quantity's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::AngularRate => "angular rate",
            Quantity::MagneticField => "magnetic field",
            Quantity::Voltage => "voltage",
            Quantity::Length => "length",
            Quantity::Temperature => "temperature",
            Quantity::Current => "current",
        }
    }

    /// The units of this quantity a map may name, with the factor that takes a value in that
    /// unit to the dataset's unit (the first entry, factor 1).
    pub fn units(self) -> &'static [(&'static str, f64)] {
        match self {
            Quantity::AngularRate => &[("rad/s", 1.0), ("deg/s", std::f64::consts::PI / 180.0)],
            // 1 G = 1e-4 T = 1e5 nT; 1 mG = 100 nT; 1 uT = 1000 nT.
            Quantity::MagneticField => &[("nT", 1.0), ("uT", 1.0e3), ("mG", 1.0e2), ("G", 1.0e5)],
            Quantity::Voltage => &[("V", 1.0), ("mV", 1.0e-3)],
            Quantity::Length => &[("km", 1.0), ("m", 1.0e-3)],
            Quantity::Temperature => &[("C", 1.0), ("K", 1.0)],
            Quantity::Current => &[("A", 1.0), ("mA", 1.0e-3)],
        }
    }

    /// The dataset-unit value of zero in `unit`: `value = x * factor + zero`. Nonzero only
    /// for kelvin (0 K is -273.15 C); every other unit is a pure factor.
    pub fn zero(self, unit: &str) -> f64 {
        match (self, unit) {
            (Quantity::Temperature, "K") => -273.15,
            _ => 0.0,
        }
    }

    /// The factor from `unit` to the dataset's unit; `None` when `unit` is not one of
    /// [`Quantity::units`] (spelling is exact: `nT`, not `nt`).
    pub fn factor(self, unit: &str) -> Option<f64> {
        self.units()
            .iter()
            .find(|(name, _)| *name == unit)
            .map(|&(_, f)| f)
    }

    /// The allowed units as a list for messages (`rad/s, deg/s`).
    pub fn allowed(self) -> String {
        let names: Vec<&str> = self.units().iter().map(|(n, _)| *n).collect();
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_match_hand_values() {
        let f = |q: Quantity, u: &str| q.factor(u).unwrap();
        assert_eq!(f(Quantity::MagneticField, "G"), 100_000.0);
        assert_eq!(f(Quantity::MagneticField, "mG"), 100.0);
        assert_eq!(f(Quantity::MagneticField, "uT"), 1000.0);
        assert_eq!(f(Quantity::MagneticField, "nT"), 1.0);
        // 180 deg/s is pi rad/s.
        let rate = 180.0 * f(Quantity::AngularRate, "deg/s");
        assert!((rate - std::f64::consts::PI).abs() < 1e-15);
        assert_eq!(f(Quantity::Length, "m") * 6_878_000.0, 6878.0);
        assert!((f(Quantity::Voltage, "mV") * 3300.0 - 3.3).abs() < 1e-15);
        assert_eq!(Quantity::MagneticField.factor("nt"), None);
        assert_eq!(Quantity::AngularRate.factor("nT"), None);
        // 293.15 K is 20 C.
        let t = Quantity::Temperature;
        assert!((293.15 * f(t, "K") + t.zero("K") - 20.0).abs() < 1e-12);
        assert_eq!(t.zero("C"), 0.0);
        assert_eq!(Quantity::Voltage.zero("V"), 0.0);
        assert!((f(Quantity::Current, "mA") * 250.0 - 0.25).abs() < 1e-15);
        assert_eq!(Quantity::Current.factor("ma"), None);
    }
}
