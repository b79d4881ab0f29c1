//! The namespace-resolved element tree the reader works on, with its checks and error helpers.

use super::{Error, NS_SSC, NS_SSD, NS_SSV};
use std::fmt;

use quick_xml::events::{BytesStart, Event};
use quick_xml::name::ResolveResult;
use quick_xml::NsReader;

/// An XML element: namespace URI, names, unqualified attributes, child elements, line.
#[derive(Debug)]
pub(super) struct Node {
    pub(super) ns: Option<String>,
    pub(super) local: String,
    pub(super) qname: String,
    attrs: Vec<(String, String)>,
    pub(super) children: Vec<Node>,
    pub(super) line: usize,
}

impl Node {
    pub(super) fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    pub(super) fn is(&self, ns: &str, local: &str) -> bool {
        self.ns.as_deref() == Some(ns) && self.local == local
    }
}

/// Which SSP namespace an element is in (`None`: no namespace at all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ns {
    Ssd,
    Ssc,
    Ssv,
    None,
}

/// The children in SSP namespaces (or in no namespace), with their namespace; elements in
/// foreign namespaces (vendor annotations, extensions) are skipped.
pub(super) fn ssp_children(n: &Node) -> impl Iterator<Item = (Ns, &str, &Node)> {
    n.children.iter().filter_map(|c| {
        let ns = match c.ns.as_deref() {
            None => Ns::None,
            Some(NS_SSD) => Ns::Ssd,
            Some(NS_SSC) => Ns::Ssc,
            Some(NS_SSV) => Ns::Ssv,
            Some(_) => return None,
        };
        Some((ns, c.local.as_str(), c))
    })
}

/// Line numbers of byte offsets (offsets asked for in increasing order, mostly).
struct Lines<'a> {
    text: &'a str,
    offset: usize,
    line: usize,
}

impl Lines<'_> {
    fn line_at(&mut self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        if offset < self.offset {
            self.offset = 0;
            self.line = 1;
        }
        let bytes = &self.text.as_bytes()[self.offset..offset];
        self.line += bytes.iter().filter(|&&b| b == b'\n').count();
        self.offset = offset;
        self.line
    }

    fn column_at(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        let start = self.text.as_bytes()[..offset]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        self.text[start..offset].chars().count() + 1
    }
}

/// Build the element tree of an XML document (namespaces resolved).
pub(super) fn parse_tree(xml: &str, file: &str) -> Result<Node, Error> {
    let mut reader = NsReader::from_str(xml);
    let mut lines = Lines {
        text: xml,
        offset: 0,
        line: 1,
    };
    let mut stack: Vec<Node> = Vec::new();
    // Per open element: whether its content is free (it is, or is inside, an ssc:Annotation).
    let mut free: Vec<bool> = Vec::new();
    let mut root: Option<Node> = None;
    let malformed = |lines: &mut Lines, pos: u64, what: String| {
        let pos = pos as usize;
        let line = lines.line_at(pos);
        Error(format!(
            "{file}: malformed XML at line {line}, column {}: {what}",
            lines.column_at(pos)
        ))
    };
    loop {
        let pos = reader.buffer_position();
        let (ns, event) = match reader.read_resolved_event() {
            Ok((ns, event)) => (owned_ns(ns), event),
            Err(e) => {
                let at = reader.error_position();
                return Err(malformed(&mut lines, at, e.to_string()));
            }
        };
        let line = lines.line_at(pos as usize);
        let inside_free = free.last().copied().unwrap_or(false);
        let start = |e: &BytesStart| -> Result<Node, Error> {
            let node = make_node(&reader, ns.clone(), e, line, file)?;
            if !inside_free {
                check_namespace(&node, file)?;
            }
            if stack.len() >= MAX_DEPTH {
                return Err(Error(format!(
                    "{file}: <{}>: elements nested deeper than {MAX_DEPTH} (line {line}), the reader's limit",
                    node.qname
                )));
            }
            Ok(node)
        };
        let (node, open) = match event {
            Event::Start(e) => (start(&e)?, true),
            Event::Empty(e) => (start(&e)?, false),
            Event::End(_) => match stack.pop() {
                Some(node) => {
                    free.pop();
                    (node, false)
                }
                None => return Err(malformed(&mut lines, pos, "unexpected end tag".into())),
            },
            Event::Text(t) if !inside_free && !stack.is_empty() => {
                let text = String::from_utf8_lossy(t.as_ref()).into_owned();
                if text.trim().is_empty() {
                    continue;
                }
                let parent = stack.last().map_or("", |n| n.qname.as_str());
                let shown: String = text.trim().chars().take(40).collect();
                return Err(Error(format!(
                    "{file}: <{parent}>: unexpected text \"{shown}\" at line {line} (SSP elements hold no text outside <ssc:Annotation>; a lost '<'?)"
                )));
            }
            Event::CData(_) if !inside_free && !stack.is_empty() => {
                let parent = stack.last().map_or("", |n| n.qname.as_str());
                return Err(Error(format!(
                    "{file}: <{parent}>: unexpected CDATA at line {line} (SSP elements hold no text outside <ssc:Annotation>)"
                )));
            }
            // An entity declared in a DTD would stand for content the reader never sees (a
            // connection, a parameter): documents with a DTD are refused, whatever it declares.
            Event::DocType(_) => {
                return Err(Error(format!(
                    "{file}: a <!DOCTYPE> declaration at line {line}: DTDs and entities are not supported"
                )))
            }
            Event::GeneralRef(r) => {
                let name = String::from_utf8_lossy(r.as_ref()).into_owned();
                let predefined =
                    r.is_char_ref() || ["lt", "gt", "amp", "apos", "quot"].contains(&name.as_str());
                if !predefined {
                    return Err(Error(format!(
                        "{file}: entity reference &{name}; at line {line}: DTDs and entities are not supported"
                    )));
                }
                if !inside_free && !stack.is_empty() {
                    let parent = stack.last().map_or("", |n| n.qname.as_str());
                    return Err(Error(format!(
                        "{file}: <{parent}>: unexpected text \"&{name};\" at line {line} (SSP elements hold no text outside <ssc:Annotation>)"
                    )));
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        if open {
            free.push(inside_free || node.is(NS_SSC, "Annotation"));
            stack.push(node);
        } else if let Some(parent) = stack.last_mut() {
            parent.children.push(node);
        } else if root.is_some() {
            return Err(malformed(
                &mut lines,
                pos,
                format!("second root element <{}>", node.qname),
            ));
        } else {
            root = Some(node);
        }
    }
    if let Some(open) = stack.last() {
        return Err(Error(format!(
            "{file}: malformed XML: end of file inside <{}> (opened at line {})",
            open.qname, open.line
        )));
    }
    root.ok_or_else(|| Error(format!("{file}: malformed XML: no root element")))
}

/// How deep elements may nest in an SSD or SSV file (the SSP structure needs about a dozen
/// levels; the limit keeps a hostile file from exhausting the stack).
pub const MAX_DEPTH: usize = 256;

/// Refuse an element outside `ssc:Annotation` in a namespace the reader does not interpret:
/// silently skipping it would drop what its author meant (a connection, a parameter set).
fn check_namespace(node: &Node, file: &str) -> Result<(), Error> {
    let Some(ns) = node.ns.as_deref() else {
        return Ok(());
    };
    if [NS_SSD, NS_SSC, NS_SSV].contains(&ns) {
        return Ok(());
    }
    let near = [NS_SSD, NS_SSC, NS_SSV]
        .into_iter()
        .find(|k| ns.trim_end_matches('/').eq_ignore_ascii_case(k));
    let hint = match near {
        Some(k) => format!(" (did you mean {k}?)"),
        None => {
            " (only SSP 1.0 elements are read; vendor content belongs in <ssc:Annotation>)".into()
        }
    };
    Err(Error(format!(
        "{file}: <{}>: namespace {ns} is not an SSP namespace the reader can interpret (line {}){hint}",
        node.qname, node.line
    )))
}

fn owned_ns(r: ResolveResult) -> Result<Option<String>, String> {
    match r {
        ResolveResult::Bound(ns) => Ok(Some(String::from_utf8_lossy(ns.as_ref()).into_owned())),
        ResolveResult::Unbound => Ok(None),
        ResolveResult::Unknown(p) => Err(String::from_utf8_lossy(&p).into_owned()),
    }
}

fn make_node(
    reader: &NsReader<&[u8]>,
    ns: Result<Option<String>, String>,
    e: &BytesStart,
    line: usize,
    file: &str,
) -> Result<Node, Error> {
    let qname = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let fail = |what: String| Error(format!("{file}: <{qname}>: {what} (line {line})"));
    let ns = ns.map_err(|p| fail(format!("undeclared namespace prefix '{p}'")))?;
    let mut attrs = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|err| fail(format!("malformed attribute: {err}")))?;
        if a.key.as_namespace_binding().is_some() {
            continue;
        }
        // Qualified attributes (xml:lang, xsi:..., vendor ones) are not SSP attributes.
        if let (ResolveResult::Bound(_), _) = reader.resolve_attribute(a.key) {
            continue;
        }
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| fail(format!("attribute '{key}': {err}")))?
            .into_owned();
        attrs.push((key, value));
    }
    Ok(Node {
        ns,
        local: String::from_utf8_lossy(e.local_name().as_ref()).into_owned(),
        qname,
        attrs,
        children: Vec::new(),
        line,
    })
}

/// Error construction for one document.
pub(super) struct Doc<'a> {
    pub(super) file: &'a str,
}

impl Doc<'_> {
    pub(super) fn err(&self, n: &Node, what: impl fmt::Display) -> Error {
        Error(format!(
            "{}: <{}>: {what} (line {})",
            self.file, n.qname, n.line
        ))
    }

    pub(super) fn unexpected(&self, child: &Node, parent: &Node) -> Error {
        self.err(
            child,
            format_args!("unexpected element inside <{}>", parent.qname),
        )
    }

    pub(super) fn attr<'n>(&self, n: &'n Node, name: &str) -> Result<&'n str, Error> {
        n.attr(name)
            .ok_or_else(|| self.err(n, format_args!("missing required attribute '{name}'")))
    }

    pub(super) fn real_attr(&self, n: &Node, name: &str) -> Result<Option<f64>, Error> {
        n.attr(name)
            .map(|v| {
                parse_double(v).ok_or_else(|| {
                    self.err(n, format_args!("attribute {name}=\"{v}\" is not a number"))
                })
            })
            .transpose()
    }
}

/// Parse an `xs:double` (`1`, `-1.5e-3`, `.5`, `INF`, `-INF`, `NaN`).
pub(super) fn parse_double(s: &str) -> Option<f64> {
    let t = s.trim();
    match t {
        "INF" | "+INF" => Some(f64::INFINITY),
        "-INF" => Some(f64::NEG_INFINITY),
        "NaN" => Some(f64::NAN),
        _ if !t.is_empty()
            && t.bytes()
                .all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b'e' | b'E')) =>
        {
            t.parse().ok()
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;

    #[test]
    fn malformed_xml() {
        let xml = sample()
            .to_ssd()
            .replace("</ssd:Connections>", "</ssd:Connection>");
        assert_err(
            &xml,
            &["SystemStructure.ssd: malformed XML at line", "column"],
        );
        assert_err("", &["no root element"]);
        let cut = &sample().to_ssd()[..200];
        assert_err(cut, &["malformed XML"]);
        assert_err(
            "<ssd:SystemStructureDescription version=\"1.0\" name=\"x\"/>",
            &["undeclared namespace prefix 'ssd'"],
        );
    }

    #[test]
    fn bad_numbers() {
        let xml = sample().to_ssd();
        let e = xml.replace("value=\"0.001\"", "value=\"abc\"");
        assert_err(
            &e,
            &[
                "<ssv:Real>",
                "parameter 'S_base': value \"abc\" is not a valid Real",
            ],
        );
        let e = xml.replace("value=\"-2147483648\"", "value=\"1.5\"");
        assert_err(
            &e,
            &["parameter 'mode': value \"1.5\" is not a valid Integer"],
        );
        let e = xml.replace("value=\"false\"", "value=\"yes\"");
        assert_err(&e, &["value \"yes\" is not a valid Boolean"]);
        let e = xml.replace("startTime=\"0.5\"", "startTime=\"soon\"");
        assert_err(
            &e,
            &[
                "<ssd:DefaultExperiment>",
                "startTime=\"soon\" is not a number",
            ],
        );
        let e = xml.replace("factor=\"-2.5\"", "factor=\"inf\"");
        assert_err(
            &e,
            &[
                "<ssc:LinearTransformation>",
                "factor=\"inf\" is not a number",
            ],
        );
        let e = xml.replace("baseStepSize=\"0.001\"", "baseStepSize=\"0\"");
        assert_err(&e, &["<osp:FixedStepAlgorithm>", "not positive"]);
        assert_eq!(parse_double("1e-3"), Some(1e-3));
        assert_eq!(parse_double(" -INF "), Some(f64::NEG_INFINITY));
        assert_eq!(parse_double(".5"), Some(0.5));
        assert_eq!(parse_double("0x10"), None);
    }
}
