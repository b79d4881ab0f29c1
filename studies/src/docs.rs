//! The tables the case studies write into the manual (`docs/case-studies.md`), between markers.

use std::path::Path;

/// The page holding the case-study tables that the demo, the sweep, the outage and case study
/// III write.
pub const CASE_STUDIES: &str = "docs/case-studies.md";

/// `page` with the text between the markers `begin` and `end` replaced by `body`; `name` is the
/// page's path, for the error.
pub fn replace_between(
    page: &str,
    name: &str,
    begin: &str,
    end: &str,
    body: &str,
) -> Result<String, String> {
    let start = page
        .find(begin)
        .ok_or(format!("{name} has no {begin} marker"))?
        + begin.len();
    let stop = page[start..]
        .find(end)
        .ok_or(format!("{name} has no {end} marker"))?
        + start;
    Ok(format!("{}\n{body}{}", &page[..start], &page[stop..]))
}

/// The text of `page` between the markers `begin` and `end` as [`replace_between`] writes it
/// (without the line break after `begin`); None when a marker is missing.
pub fn between<'a>(page: &'a str, begin: &str, end: &str) -> Option<&'a str> {
    let start = page.find(begin)? + begin.len();
    let stop = page[start..].find(end)? + start;
    let body = &page[start..stop];
    Some(body.strip_prefix('\n').unwrap_or(body))
}

/// Whether the table between `begin` and `end` on the page `name` (relative to `root`) is
/// `fresh`, as its command would write it: an error naming `command` when it is stale.
pub fn check_between(
    root: &Path,
    name: &str,
    begin: &str,
    end: &str,
    fresh: &str,
    command: &str,
) -> Result<(), String> {
    let path = root.join(name);
    let page = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let written = between(&page, begin, end).ok_or(format!("{name} has no {begin} … {end}"))?;
    if written == fresh {
        Ok(())
    } else {
        Err(format!(
            "{name}: the table {begin} is stale (run `{command}`); it reads\n{written}\nand the run gives\n{fresh}"
        ))
    }
}

/// Rewrite the text between the markers `begin` and `end` of the page `name` (a path relative
/// to `root`, such as [`CASE_STUDIES`]) with `body`.
pub fn update_between(
    root: &Path,
    name: &str,
    begin: &str,
    end: &str,
    body: &str,
) -> Result<(), String> {
    let path = root.join(name);
    let page = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let fresh = replace_between(&page, name, begin, end, body)?;
    std::fs::write(&path, fresh).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    fn root() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .expect("workspace root")
            .to_path_buf()
    }

    /// The markers `cargo xtask demo`, `sweep`, `outage` and `case3` write between are on the
    /// page they write to, once each, in order.
    #[test]
    fn case_study_page_has_the_generated_tables() {
        let page = std::fs::read_to_string(root().join(super::CASE_STUDIES)).unwrap();
        for (begin, end) in [
            ("<!-- metrics:begin -->", "<!-- metrics:end -->"),
            ("<!-- case2:begin -->", "<!-- case2:end -->"),
            ("<!-- outage:begin -->", "<!-- outage:end -->"),
            ("<!-- case3:begin -->", "<!-- case3:end -->"),
        ] {
            assert_eq!(page.matches(begin).count(), 1, "{begin}");
            assert_eq!(page.matches(end).count(), 1, "{end}");
            let body = &page[page.find(begin).unwrap()..page.find(end).unwrap()];
            // Rewriting with the same body leaves the page as it is.
            let inner = body[begin.len()..].strip_prefix('\n').unwrap();
            assert_eq!(super::between(&page, begin, end), Some(inner));
            let same =
                super::replace_between(&page, super::CASE_STUDIES, begin, end, inner).unwrap();
            assert!(
                same == page,
                "{begin}: the table is not where the command writes it"
            );
        }
    }
}
