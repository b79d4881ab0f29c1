//! SVG text: rendered widths, escaping and the printing of numbers.

use super::TICK_FONT;

/// Rough rendered width of `text` in DejaVu Sans at `size` px (good enough for layout).
pub(super) fn text_width(text: &str, size: f64) -> f64 {
    text.chars()
        .map(|ch| match ch {
            '0'..='9' => 0.64,
            '.' | ',' | ':' | ';' | 'i' | 'l' | 'j' | '|' | '!' | '\'' | 'I' => 0.3,
            ' ' => 0.32,
            '-' | '(' | ')' | '[' | ']' | '/' | 'f' | 't' | 'r' => 0.4,
            '\u{2212}' | '+' | '=' | '<' | '>' => 0.84,
            'm' | 'w' => 0.95,
            'M' | 'W' => 0.95,
            'A'..='Z' => 0.72,
            'a'..='z' => 0.6,
            _ => 0.75,
        })
        .sum::<f64>()
        * size
}

/// Estimated width of a tick label as rendered (with its typographic minus).
pub(super) fn tick_width(label: &str) -> f64 {
    text_width(&minus(label), TICK_FONT)
}

/// Tick labels use a typographic minus sign (U+2212), as matplotlib does.
pub(super) fn minus(label: &str) -> String {
    label.replace('-', "\u{2212}")
}

/// XML-escapes text and attribute values.
pub(super) fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Control characters are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A coordinate with at most one decimal ("12.5", "12"); non-finite values become 0.
pub(super) fn c(v: f64) -> String {
    if !v.is_finite() {
        return "0".into();
    }
    let r = (v * 10.0).round() / 10.0;
    let s = format!("{r:.1}");
    let s = s.strip_suffix(".0").unwrap_or(&s).to_string();
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

pub(super) fn finite_or(v: f64, default: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        default
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping_and_coordinates() {
        assert_eq!(
            esc("a<b & 'c' \"d\">"),
            "a&lt;b &amp; &apos;c&apos; &quot;d&quot;&gt;"
        );
        assert_eq!(c(12.04), "12");
        assert_eq!(c(12.06), "12.1");
        assert_eq!(c(-0.01), "0");
        assert_eq!(c(f64::NAN), "0");
    }
}
