//! Digests of full-rate results: one hash per column and per block of rows, so that a machine whose results differ from the committed ones is told the first column and time that differ.
//!
//! The hash is FNV-1a (64 bit) over each value's IEEE bits, little-endian: a change in the last
//! bit of one value in one row changes its column's digest and its block's. It detects change;
//! it is no protection against a crafted collision, which nobody here has a reason to make.

use std::fmt::Write as _;
use std::path::Path;

/// Results as columns: `time` first, then every recorded output, as `cosim` writes them.
pub struct Table {
    /// Column names, `time` first.
    pub names: Vec<String>,
    /// One vector per column, all of one length.
    pub columns: Vec<Vec<f64>>,
}

impl Table {
    /// Read a CSV that `cosim --out` wrote (its numbers read back to the same bits).
    pub fn read_csv(path: &Path) -> Result<Table, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut lines = text.lines();
        let names: Vec<String> = lines
            .next()
            .ok_or_else(|| format!("{}: empty", path.display()))?
            .split(',')
            .map(|s| s.trim_matches('"').to_string())
            .collect();
        let mut columns = vec![Vec::new(); names.len()];
        for (k, line) in lines.enumerate() {
            let values: Vec<&str> = line.split(',').collect();
            if values.len() != names.len() {
                return Err(format!(
                    "{}: row {} has {} values for {} columns",
                    path.display(),
                    k + 1,
                    values.len(),
                    names.len()
                ));
            }
            for (c, v) in columns.iter_mut().zip(values) {
                c.push(
                    v.parse::<f64>()
                        .map_err(|e| format!("{}: row {}: {v:?}: {e}", path.display(), k + 1))?,
                );
            }
        }
        Ok(Table { names, columns })
    }

    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }
}

/// FNV-1a, 64 bit, of the values' bits.
fn fnv1a(values: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// The digest of a [`Table`]: per column, the hash of the whole column and of each block of
/// `block` rows, and the time at each block's first row.
#[derive(Debug, PartialEq)]
pub struct Digest {
    /// Rows per block.
    pub block: usize,
    /// Rows in all.
    pub rows: usize,
    /// The time at each block's first row.
    pub block_times: Vec<f64>,
    /// Per column: name, whole-column hash, per-block hashes.
    pub columns: Vec<(String, u64, Vec<u64>)>,
}

impl Digest {
    /// The digest of `t` with blocks of `block` rows.
    pub fn of(t: &Table, block: usize) -> Digest {
        assert!(block > 0);
        let time = t.columns.first().map(Vec::as_slice).unwrap_or(&[]);
        Digest {
            block,
            rows: t.rows(),
            block_times: time.iter().step_by(block).copied().collect(),
            columns: t
                .names
                .iter()
                .zip(&t.columns)
                .map(|(n, c)| (n.clone(), fnv1a(c), c.chunks(block).map(fnv1a).collect()))
                .collect(),
        }
    }

    /// The text committed under `tests/digests/`: `header` as comment lines, then `rows`,
    /// `block`, the block times, and a line per column (name, whole hash, block hashes).
    pub fn to_text(&self, header: &str) -> String {
        let mut s = String::new();
        for l in header.lines() {
            let _ = writeln!(s, "# {l}");
        }
        let _ = writeln!(s, "rows {}", self.rows);
        let _ = writeln!(s, "block {}", self.block);
        let times: Vec<String> = self.block_times.iter().map(|t| format!("{t}")).collect();
        let _ = writeln!(s, "block_times {}", times.join(" "));
        for (name, whole, blocks) in &self.columns {
            let b: Vec<String> = blocks.iter().map(|h| format!("{h:016x}")).collect();
            let _ = writeln!(s, "column {name} {whole:016x} {}", b.join(" "));
        }
        s
    }

    /// Parse what [`Digest::to_text`] wrote.
    pub fn parse(text: &str) -> Result<Digest, String> {
        let (mut rows, mut block, mut block_times, mut columns) = (None, None, None, Vec::new());
        let hex = |h: &str| u64::from_str_radix(h, 16).map_err(|e| format!("{h:?}: {e}"));
        for line in text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
        {
            let mut w = line.split_whitespace();
            match w.next() {
                Some("rows") => rows = w.next().and_then(|x| x.parse().ok()),
                Some("block") => block = w.next().and_then(|x| x.parse().ok()),
                Some("block_times") => {
                    block_times = Some(
                        w.map(|x| x.parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
                            .collect::<Result<Vec<_>, _>>()?,
                    )
                }
                Some("column") => {
                    let name = w.next().ok_or("a column line without a name")?.to_string();
                    let whole = hex(w.next().ok_or("a column line without its hash")?)?;
                    let blocks = w.map(hex).collect::<Result<Vec<_>, _>>()?;
                    columns.push((name, whole, blocks));
                }
                _ => return Err(format!("unexpected line {line:?}")),
            }
        }
        Ok(Digest {
            rows: rows.ok_or("no rows line")?,
            block: block.ok_or("no block line")?,
            block_times: block_times.ok_or("no block_times line")?,
            columns,
        })
    }

    /// `None` when `self` (this machine's) equals `expected`; otherwise where they first
    /// differ: the first block (in time) where any column differs, and the columns that differ
    /// there, in the table's order.
    pub fn first_difference(&self, expected: &Digest) -> Option<String> {
        if self == expected {
            return None;
        }
        if self.block != expected.block {
            return Some(format!(
                "blocks of {} rows against the expected {}",
                self.block, expected.block
            ));
        }
        let names = |d: &Digest| d.columns.iter().map(|c| c.0.clone()).collect::<Vec<_>>();
        if names(self) != names(expected) {
            let (a, b) = (names(self), names(expected));
            let missing: Vec<&String> = b.iter().filter(|n| !a.contains(n)).collect();
            let extra: Vec<&String> = a.iter().filter(|n| !b.contains(n)).collect();
            return Some(format!(
                "other columns: missing {missing:?}, not expected {extra:?} ({} against {})",
                a.len(),
                b.len()
            ));
        }
        let blocks = self.rows.min(expected.rows).div_ceil(self.block);
        for k in 0..blocks {
            let differ: Vec<&str> = self
                .columns
                .iter()
                .zip(&expected.columns)
                .filter(|(a, b)| a.2.get(k) != b.2.get(k))
                .map(|(a, _)| a.0.as_str())
                .collect();
            if let Some(first) = differ.first() {
                let t0 = expected.block_times.get(k).copied().unwrap_or(f64::NAN);
                let t1 = expected.block_times.get(k + 1).copied();
                let until = t1.map_or("the end".to_string(), |t| format!("{t} s"));
                return Some(format!(
                    "first in column `{first}` between t = {t0} s and {until} (rows {} to {}); \
                     {} of {} columns differ there: {}",
                    k * self.block,
                    ((k + 1) * self.block).min(self.rows) - 1,
                    differ.len(),
                    self.columns.len(),
                    differ.join(", ")
                ));
            }
        }
        Some(format!(
            "{} rows against the expected {} (the common rows agree)",
            self.rows, expected.rows
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(n: usize) -> Table {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let x: Vec<f64> = t.iter().map(|t| t * t).collect();
        let y: Vec<f64> = t.iter().map(|t| 1.0 - t).collect();
        Table {
            names: vec!["time".into(), "a.x".into(), "b.y".into()],
            columns: vec![t, x, y],
        }
    }

    #[test]
    fn a_last_bit_names_its_column_and_block() {
        let mut t = table(1000);
        let d = Digest::of(&t, 100);
        let back = Digest::parse(&d.to_text("header\nsecond line")).unwrap();
        assert_eq!(back, d);
        assert_eq!(d.first_difference(&back), None);
        t.columns[2][457] = f64::from_bits(t.columns[2][457].to_bits() ^ 1);
        let msg = Digest::of(&t, 100).first_difference(&d).unwrap();
        assert!(
            msg.contains("column `b.y` between t = 0.4 s and 0.5 s (rows 400 to 499)")
                && msg.contains("1 of 3 columns"),
            "{msg}"
        );
    }

    #[test]
    fn other_columns_or_rows_are_named() {
        let d = Digest::of(&table(1000), 100);
        let mut t = table(1000);
        t.names[1] = "a.z".into();
        let msg = Digest::of(&t, 100).first_difference(&d).unwrap();
        assert!(msg.contains("missing [\"a.x\"]"), "{msg}");
        let msg = Digest::of(&table(900), 100).first_difference(&d).unwrap();
        assert!(msg.contains("900 rows against the expected 1000"), "{msg}");
    }
}
