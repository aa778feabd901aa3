//! Current columns of telemetry.csv, `cur_<name>_A`: telemetry channels (panel and battery
//! currents, torquer commands) that may drive a magnetometer bias (docs/magcal.md). Kept
//! raw; the magnetometer calibration tests each one as a regressor.

/// Plausible currents of a small spacecraft's channels, amperes (inclusive). Far wider than
/// any bus, so a cell outside is a unit mistake (milliamperes or counts in an `_A` column).
pub const CURRENT_RANGE_A: (f64, f64) = (-100.0, 100.0);

/// One current column of telemetry.csv, as in the file.
#[derive(Clone, Debug, PartialEq)]
pub struct CurrentColumn {
    /// The header, `cur_<name>_A`.
    pub name: String,
    /// Amperes per row; `None` is an empty cell (not sampled at that row).
    pub values: Vec<Option<f64>>,
}

/// The header of the current channel `name`: `cur_<name>_A`.
pub fn current_column(name: &str) -> String {
    format!("cur_{name}_A")
}

/// Longest current channel name, characters: every output that names a channel (the
/// figure `residual_cur_<name>_a` of `magcal`, a file name of at most 100 characters) has
/// room for it, and a telemetry channel's name is a word or two.
pub const MAX_CURRENT_NAME_CHARS: usize = 64;

/// Whether `name` may name a current channel: ASCII `a-z`, `0-9`, `_`, not empty, at most
/// [`MAX_CURRENT_NAME_CHARS`].
pub fn is_current_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_CURRENT_NAME_CHARS
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
}

/// Classifies a header: `None` when it is not a current column at all (no `cur_`),
/// `Some(Ok(name))` for `cur_<name>_A` with a valid name, `Some(Err(()))` otherwise.
pub(crate) fn current_key(header: &str) -> Option<Result<&str, ()>> {
    let rest = header.strip_prefix("cur_")?;
    Some(
        rest.strip_suffix("_A")
            .filter(|name| is_current_name(name))
            .ok_or(()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys() {
        assert_eq!(current_key("pd01_V"), None);
        assert_eq!(current_key("cur_px_A"), Some(Ok("px")));
        assert_eq!(current_key("cur_battery_2_A"), Some(Ok("battery_2")));
        assert_eq!(current_key("cur_px_mA"), Some(Err(())));
        assert_eq!(current_key("cur_Px_A"), Some(Err(())));
        assert_eq!(current_key("cur__A"), Some(Err(())));
        assert_eq!(current_column("px"), "cur_px_A");
    }
}
