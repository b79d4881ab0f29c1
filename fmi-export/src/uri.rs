//! From an FMI resource location (a `file:` URI per FMI 2.0 and RFC 8089) to a Linux or Windows path.
//!
//! The conversion is a pure function of the text and the [`PathStyle`], so that both styles are
//! tested on any host; [`resource_path`] applies the host's style.
//!
//! Accepted (`%XX` escapes decoded in host and path, the scheme and `localhost` in any case):
//!
//! | location | Unix | Windows |
//! |---|---|---|
//! | `file:///a/b`, `file:/a/b`, `file://localhost/a/b` | `/a/b` | `\a\b` |
//! | `file:///C:/a`, `file:/C:/a`, `file:C:/a`, `file://localhost/C:/a`, `file:///C\|/a` | the path as written (`/C:/a`: a directory `C:`) | `C:\a` |
//! | `file://C:/a` (drive letter in the host part, written by naive `"file://" + path`) | error | `C:\a` |
//! | `file://server/share/a`, `file:////server/share/a` | error (remote host) | `\\server\share\a` |
//! | a plain path (no scheme), e.g. `/a b` or `C:\a b` | itself, not decoded | itself, not decoded |
//!
//! Anything else with a `scheme://` is refused as not a file URI.

use std::path::PathBuf;

/// The path syntax a resource location is turned into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathStyle {
    /// `/`-separated; a URI naming a host other than `localhost` is refused.
    Unix,
    /// Drive letters (`C:\`), `\` separators, and UNC shares (`\\server\share`) for a host.
    Windows,
}

impl PathStyle {
    /// The style of the platform this library was built for.
    pub const HOST: PathStyle = if cfg!(windows) {
        PathStyle::Windows
    } else {
        PathStyle::Unix
    };
}

/// Decode an FMI resource location into a path of the host platform (see the module doc for the
/// accepted forms).
pub fn resource_path(uri: &str) -> Result<PathBuf, String> {
    resource_path_for(uri, PathStyle::HOST).map(PathBuf::from)
}

/// Decode an FMI resource location into a path in `style`; errors are one line naming `uri`.
pub fn resource_path_for(uri: &str, style: PathStyle) -> Result<String, String> {
    let err = |what: &str| format!("resource location '{uri}' {what}");
    let Some(rest) = strip_prefix_ignore_case(uri, "file:") else {
        if uri.contains("://") {
            return Err(err("is not a file URI"));
        }
        // A plain path, as some hosts pass: taken as it is.
        return Ok(uri.to_owned());
    };
    let windows = style == PathStyle::Windows;
    // Split `//authority/path`; without `//` there is no authority (`file:/a`, `file:C:/a`).
    let (host, path) = match rest.strip_prefix("//") {
        // `file://C:/a` (or `file://C:\a`): a drive letter where the host belongs.
        Some(r) if windows && drive_prefix(r).is_some() => ("", r),
        Some(r) => match r.find('/') {
            Some(slash) => r.split_at(slash),
            None => (r, ""),
        },
        None => ("", rest),
    };
    let host = decode(host).ok_or_else(|| err(BAD_ESCAPE))?;
    let path = decode(path).ok_or_else(|| err(BAD_ESCAPE))?;
    if path.contains('\0') || host.contains('\0') {
        return Err(err("contains a NUL character (%00)"));
    }
    let remote = !host.is_empty() && !host.eq_ignore_ascii_case("localhost");
    match style {
        PathStyle::Unix => {
            if remote {
                return Err(err(&format!(
                    "names the remote host '{host}'; only local files can be read here \
                     (file:///path or file://localhost/path)"
                )));
            }
            if path.is_empty() {
                return Err(err("has no path"));
            }
            Ok(path)
        }
        PathStyle::Windows => {
            let path = path.replace('/', "\\");
            if remote {
                // `file://server/share/a` is the UNC path `\\server\share\a`.
                if host.contains(['\\', ':']) {
                    return Err(err(&format!("names the host '{host}', not a server name")));
                }
                if path.trim_start_matches('\\').split('\\').next() == Some("") {
                    return Err(err(&format!(
                        "names the server '{host}' but no share (file://server/share/path)"
                    )));
                }
                return Ok(format!("\\\\{host}{path}"));
            }
            if let Some(unc) = path.strip_prefix("\\\\") {
                // `file:////server/share/a`: a UNC path written as the URI's path.
                let unc = unc.trim_start_matches('\\');
                if unc.is_empty() {
                    return Err(err("has no path"));
                }
                return Ok(format!("\\\\{unc}"));
            }
            // `\C:\a` (from `file:///C:/a`) or `C:\a` (from `file:C:/a`); `|` for `:` is the
            // legacy spelling of a drive.
            let unrooted = path.strip_prefix('\\').unwrap_or(&path);
            if let Some(letter) = drive_prefix(unrooted) {
                let after = &unrooted[2..];
                let after = if after.is_empty() { "\\" } else { after };
                return Ok(format!("{letter}:{after}"));
            }
            if path.is_empty() {
                return Err(err("has no path"));
            }
            Ok(path)
        }
    }
}

const BAD_ESCAPE: &str = "has a bad percent-escape or is not UTF-8 once decoded";

/// `s` without the ASCII `prefix`, compared case-insensitively.
fn strip_prefix_ignore_case<'a>(s: &'a str, prefix: &str) -> Option<&'a str> {
    let head = s.get(..prefix.len())?;
    head.eq_ignore_ascii_case(prefix)
        .then(|| &s[prefix.len()..])
}

/// The letter if `s` begins with a drive, `X:` or `X|`, followed by a separator or the end.
fn drive_prefix(s: &str) -> Option<char> {
    let b = s.as_bytes();
    let letter = *b.first()?;
    let ok = letter.is_ascii_alphabetic()
        && matches!(b.get(1), Some(b':' | b'|'))
        && matches!(b.get(2), None | Some(b'/' | b'\\'));
    ok.then_some(letter as char)
}

/// Decode `%XX` escapes; `None` if one is malformed or the result is not UTF-8.
fn decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            if !hex.bytes().all(|c| c.is_ascii_hexdigit()) {
                return None;
            }
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::PathStyle::{Unix, Windows};
    use super::*;

    fn ok(uri: &str, style: PathStyle) -> String {
        resource_path_for(uri, style).unwrap_or_else(|e| panic!("{style:?}: {e}"))
    }

    fn fails(uri: &str, style: PathStyle, part: &str) {
        let e = resource_path_for(uri, style).expect_err(uri);
        assert!(e.contains(part), "{style:?} {uri}: {e}");
        assert!(e.contains(uri) && !e.contains('\n'), "{e}");
    }

    #[test]
    fn unix_local_forms() {
        for (uri, path) in [
            ("file:///tmp/fmu/resources", "/tmp/fmu/resources"),
            ("file:/tmp/fmu/resources", "/tmp/fmu/resources"),
            ("file://localhost/tmp/fmu/resources/", "/tmp/fmu/resources/"),
            ("file://LOCALHOST/tmp/r", "/tmp/r"),
            ("FILE:///tmp/r", "/tmp/r"),
            ("file:///tmp/dvpp%20res/r%C3%A9s", "/tmp/dvpp res/rés"),
            ("file:///tmp/100%25", "/tmp/100%"),
            ("/tmp/plain path", "/tmp/plain path"),
            ("/tmp/plain%20stays", "/tmp/plain%20stays"),
            // A drive letter means nothing on Unix: a directory named `C:`.
            ("file:///C:/dir", "/C:/dir"),
        ] {
            assert_eq!(ok(uri, Unix), path, "{uri}");
        }
    }

    #[test]
    fn unix_refuses_remote_hosts_and_other_schemes() {
        fails(
            "file://server/share/resources",
            Unix,
            "remote host 'server'",
        );
        fails("file://C:/dir", Unix, "remote host 'C:'");
        fails("http://example.org/resources", Unix, "not a file URI");
        fails("file:///tmp/%2", Unix, "bad percent-escape");
        fails("file:///tmp/%zz", Unix, "bad percent-escape");
        fails("file:///tmp/%FF", Unix, "not UTF-8");
        fails("file:///tmp/%00", Unix, "NUL");
        fails("file://", Unix, "has no path");
    }

    #[test]
    fn windows_drive_letters() {
        for (uri, path) in [
            ("file:///C:/dir/resources", r"C:\dir\resources"),
            ("file:/C:/dir/resources", r"C:\dir\resources"),
            ("file:C:/dir/resources", r"C:\dir\resources"),
            ("file://localhost/C:/dir/resources", r"C:\dir\resources"),
            ("file:///C|/dir/resources", r"C:\dir\resources"),
            ("file:///c:/dir/resources/", r"c:\dir\resources\"),
            ("file:///C:", r"C:\"),
            ("file:///C:/", r"C:\"),
            (
                "file:///C:/Program%20Files/dvpp/resources",
                r"C:\Program Files\dvpp\resources",
            ),
            (
                "file:///Z:/tmp/fmu%20x/resources",
                r"Z:\tmp\fmu x\resources",
            ),
            ("file://C:/dir", r"C:\dir"),
            (r"file://C:\dir\resources", r"C:\dir\resources"),
            ("file:///dir/resources", r"\dir\resources"),
            (r"C:\Program Files\plain", r"C:\Program Files\plain"),
        ] {
            assert_eq!(ok(uri, Windows), path, "{uri}");
        }
    }

    #[test]
    fn windows_unc_shares() {
        for (uri, path) in [
            ("file://server/share/x", r"\\server\share\x"),
            (
                "file://server/share/fmu%20dir/resources",
                r"\\server\share\fmu dir\resources",
            ),
            ("file:////server/share/x", r"\\server\share\x"),
            ("file://///server/share/x", r"\\server\share\x"),
        ] {
            assert_eq!(ok(uri, Windows), path, "{uri}");
        }
        fails("file://server", Windows, "no share");
        fails("file://server/", Windows, "no share");
        fails("file://server:445/share", Windows, "not a server name");
        fails("https://server/share", Windows, "not a file URI");
        fails("file:///C:/Program%2", Windows, "bad percent-escape");
    }

    #[test]
    fn the_host_style_is_the_build_target() {
        let expected = if cfg!(windows) { r"C:\a" } else { "/C:/a" };
        assert_eq!(
            resource_path("file:///C:/a").unwrap(),
            PathBuf::from(expected)
        );
    }
}
