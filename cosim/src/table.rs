//! Results in memory and as CSV, and the master's integer clock (nanosecond ticks).

use std::io::Write;

/// Simulation results: `time` then one column per recorded variable.
#[derive(Debug, Clone, Default)]
pub struct Table {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// The values of column `name`.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

impl dvpp_report::Columns for Table {
    fn names(&self) -> &[String] {
        &self.columns
    }

    fn column(&self, name: &str) -> Option<Vec<f64>> {
        Table::column(self, name)
    }
}

/// One CSV field per RFC 4180: quoted (with `"` doubled) when it holds a comma, a quote, a line
/// break or leading/trailing blanks, as it is otherwise.
pub fn csv_field(name: &str) -> std::borrow::Cow<'_, str> {
    let needs = name.contains([',', '"', '\n', '\r'])
        || name.starts_with([' ', '\t'])
        || name.ends_with([' ', '\t']);
    if needs {
        format!("\"{}\"", name.replace('"', "\"\"")).into()
    } else {
        name.into()
    }
}

/// The header line: the column names, quoted where RFC 4180 needs it.
pub fn write_header(w: &mut impl Write, columns: &[String]) -> std::io::Result<()> {
    for (k, c) in columns.iter().enumerate() {
        if k > 0 {
            w.write_all(b",")?;
        }
        w.write_all(csv_field(c).as_bytes())?;
    }
    w.write_all(b"\n")
}

/// One row of numbers, each the shortest text that reads back as the same `f64` (`NaN`, `inf`
/// and `-inf` for the non-finite).
pub fn write_row(w: &mut impl Write, row: &[f64]) -> std::io::Result<()> {
    let mut text = ryu::Buffer::new();
    for (k, x) in row.iter().enumerate() {
        if k > 0 {
            w.write_all(b",")?;
        }
        w.write_all(text.format(*x).as_bytes())?;
    }
    w.write_all(b"\n")
}

/// Nanoseconds per second: the master counts time in integer ticks.
pub const NS: i64 = 1_000_000_000;

/// The largest time the master represents, s (`i64` nanoseconds reach about 9.2e9 s).
pub const MAX_TIME: f64 = 9.0e9;

/// Seconds to ticks, rounded to the nearest nanosecond; `None` when `seconds` is not finite or
/// beyond ±[`MAX_TIME`].
pub fn ticks(seconds: f64) -> Option<i64> {
    (seconds.is_finite() && seconds.abs() <= MAX_TIME).then(|| (seconds * NS as f64).round() as i64)
}

/// Ticks to seconds.
pub fn seconds(ticks: i64) -> f64 {
    ticks as f64 / NS as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_quoted_only_when_needed() {
        assert_eq!(csv_field("der[1].p"), "der[1].p");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(csv_field("two\nlines"), "\"two\nlines\"");
        assert_eq!(csv_field(" padded"), "\" padded\"");
        let mut out = Vec::new();
        write_header(&mut out, &["time".into(), "x,y".into()]).unwrap();
        write_row(&mut out, &[0.1, f64::NAN, f64::NEG_INFINITY, 1e-300, -2.0]).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "time,\"x,y\"\n0.1,NaN,-inf,1e-300,-2.0\n"
        );
    }

    #[test]
    fn ticks_refuse_what_i64_nanoseconds_cannot_hold() {
        assert_eq!(ticks(1.5), Some(1_500_000_000));
        assert_eq!(ticks(-2.0), Some(-2_000_000_000));
        assert_eq!(ticks(MAX_TIME), Some(9_000_000_000_000_000_000));
        for bad in [1e12, -1e10, -1e308, f64::NAN, f64::INFINITY] {
            assert_eq!(ticks(bad), None, "{bad}");
        }
    }
}
