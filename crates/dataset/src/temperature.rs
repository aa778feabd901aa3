//! Temperature columns of telemetry.csv: `temp_pdNN_C` for one photodiode, `temp_<panel>_C`
//! for every photodiode whose dataset.ron entry says `panel: "<panel>"`; and the
//! per-photodiode temperatures a measurement model reads from them, row by row.

/// Plausible temperatures of a spacecraft photodiode, degrees Celsius (inclusive). Wider than
/// any survivable range, so a cell outside is a unit or sign mistake (kelvin, Fahrenheit),
/// not a hot sensor.
pub const TEMPERATURE_RANGE_C: (f64, f64) = (-150.0, 150.0);

/// One temperature column of telemetry.csv, as in the file.
#[derive(Clone, Debug, PartialEq)]
pub struct TemperatureColumn {
    /// The header, `temp_pd03_C` or `temp_<panel>_C`.
    pub name: String,
    /// Degrees Celsius per row; `None` is an empty cell (not sampled at that row).
    pub values: Vec<Option<f64>>,
}

/// The header of the temperature of photodiode `index` (1-based), padded like
/// [`crate::photodiode_column`]: `temp_pd01_C`, ..., `temp_pd100_C`.
pub fn photodiode_temperature_column(index: usize) -> String {
    format!("temp_pd{index:02}_C")
}

/// The header of the temperature of panel `panel`: `temp_<panel>_C`.
pub fn panel_temperature_column(panel: &str) -> String {
    format!("temp_{panel}_C")
}

/// Whether `name` may name a panel: ASCII `a-z`, `0-9`, `_`, not empty, and not `pd`
/// followed by a digit (that spelling belongs to the per-photodiode columns).
pub fn is_panel_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
        && !looks_like_photodiode(name)
}

fn looks_like_photodiode(key: &str) -> bool {
    key.strip_prefix("pd")
        .and_then(|rest| rest.bytes().next())
        .is_some_and(|b| b.is_ascii_digit())
}

/// What a `temp_*_C` header refers to.
#[derive(Debug, PartialEq)]
pub(crate) enum TemperatureKey<'a> {
    /// `temp_pd<digits>_C`: the 1-based photodiode index (`usize::MAX` when it overflows).
    Photodiode(usize),
    /// `temp_<panel>_C` with a valid panel name.
    Panel(&'a str),
    /// Starts with `temp_` but is neither.
    Malformed,
}

/// Classifies a header: `None` when it is not a temperature column at all (no `temp_`).
pub(crate) fn temperature_key(name: &str) -> Option<TemperatureKey<'_>> {
    let rest = name.strip_prefix("temp_")?;
    let Some(key) = rest.strip_suffix("_C") else {
        return Some(TemperatureKey::Malformed);
    };
    if looks_like_photodiode(key) {
        let digits = &key[2..];
        if !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Some(TemperatureKey::Malformed);
        }
        return Some(TemperatureKey::Photodiode(
            digits.parse().unwrap_or(usize::MAX),
        ));
    }
    Some(if is_panel_name(key) {
        TemperatureKey::Panel(key)
    } else {
        TemperatureKey::Malformed
    })
}

/// Each photodiode's temperature at a row, degrees Celsius, held from the latest sample at
/// or before that row: temperatures change over minutes, so an empty cell means "unchanged
/// since the last sample", not "unknown". NaN before a column's first sample and for a
/// photodiode without a column.
///
/// Allocates once when made; [`HeldTemperatures::at`] does not allocate. Rows are cheapest
/// in increasing order (each cell is read once); going back rescans from the first row.
#[derive(Clone, Debug)]
pub struct HeldTemperatures<'a> {
    columns: &'a [TemperatureColumn],
    of_photodiode: Vec<Option<usize>>,
    held_c: Vec<f64>,
    row_c: Vec<f64>,
    next_row: usize,
}

impl<'a> HeldTemperatures<'a> {
    /// Held temperatures of `photodiodes` photodiodes over `columns`, photodiode `i` reading
    /// column `of_photodiode[i]` (empty when there are no columns).
    pub(crate) fn new(
        columns: &'a [TemperatureColumn],
        of_photodiode: Vec<Option<usize>>,
        photodiodes: usize,
    ) -> Self {
        let with_columns = !columns.is_empty();
        let n_columns = columns.len();
        HeldTemperatures {
            columns,
            of_photodiode,
            held_c: vec![f64::NAN; n_columns],
            row_c: if with_columns {
                vec![f64::NAN; photodiodes]
            } else {
                Vec::new()
            },
            next_row: 0,
        }
    }

    /// The temperatures at row `row`, one per photodiode; empty when the telemetry has no
    /// temperature columns. A row past the end holds the last samples.
    pub fn at(&mut self, row: usize) -> &[f64] {
        if self.columns.is_empty() {
            return &[];
        }
        if row < self.next_row.saturating_sub(1) {
            self.held_c.fill(f64::NAN);
            self.next_row = 0;
        }
        for (held, column) in self.held_c.iter_mut().zip(self.columns) {
            let upto = column.values.len().min(row + 1);
            let from = self.next_row.min(upto);
            if let Some(v) = column.values[from..upto].iter().rev().find_map(|v| *v) {
                *held = v;
            }
        }
        self.next_row = self.next_row.max(row + 1);
        for (t, column) in self.row_c.iter_mut().zip(&self.of_photodiode) {
            *t = column
                .and_then(|c| self.held_c.get(c).copied())
                .unwrap_or(f64::NAN);
        }
        &self.row_c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys() {
        use TemperatureKey::*;
        assert_eq!(temperature_key("pd01_V"), None);
        assert_eq!(temperature_key("temp_pd03_C"), Some(Photodiode(3)));
        assert_eq!(temperature_key("temp_pd3_C"), Some(Photodiode(3)));
        assert_eq!(temperature_key("temp_x_plus_C"), Some(Panel("x_plus")));
        assert_eq!(temperature_key("temp_pdb_C"), Some(Panel("pdb")));
        assert_eq!(temperature_key("temp_pd3a_C"), Some(Malformed));
        assert_eq!(temperature_key("temp_Xplus_C"), Some(Malformed));
        assert_eq!(temperature_key("temp__C"), Some(Malformed));
        assert_eq!(temperature_key("temp_xplus_K"), Some(Malformed));
        assert_eq!(
            temperature_key("temp_pd99999999999999999999999_C"),
            Some(Photodiode(usize::MAX))
        );
    }
}
