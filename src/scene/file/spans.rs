//! Where each value of a scene file was written, found by the field path
//! an error names (`object[2].radius`), so that an error points at the
//! line of the value at fault, not at the header of its table.
//!
//! Promises: [`value_span`] gives the span of the deepest part of the path
//! that the text wrote (a table, when the field itself was left out), and
//! None when not even the path's first key was written or the text does
//! not parse; the caller then keeps the span it had.

use std::ops::Range;

use serde::de::{Deserialize, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};

/// A TOML value, reduced to where its parts were written.
enum Node {
    Leaf,
    /// A float, kept to check it fits the renderer's 32-bit numbers.
    Float(f64),
    Table(Vec<(String, Located)>),
    Array(Vec<Located>),
}

/// A value and its span: none for a table only implied by a header
/// (`[material.red]` implies `material`), which `toml::Spanned` refuses.
struct Located {
    span: Option<Range<usize>>,
    node: Node,
}

/// The names of the private protocol by which toml hands `toml::Spanned`
/// its span (serde_spanned's `__unstable`, which this crate cannot name).
const SPANNED: &str = "$__serde_spanned_private_Spanned";
const START: &str = "$__serde_spanned_private_start";
const END: &str = "$__serde_spanned_private_end";
const VALUE: &str = "$__serde_spanned_private_value";

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Node, D::Error> {
        Ok(deserializer.deserialize_any(LocatedVisitor)?.node)
    }
}

impl<'de> Deserialize<'de> for Located {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Located, D::Error> {
        deserializer.deserialize_struct(SPANNED, &[START, END, VALUE], LocatedVisitor)
    }
}

struct LocatedVisitor;

impl LocatedVisitor {
    fn leaf<E>(self) -> Result<Located, E> {
        Ok(Located {
            span: None,
            node: Node::Leaf,
        })
    }
}

impl<'de> Visitor<'de> for LocatedVisitor {
    type Value = Located;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a TOML value")
    }

    fn visit_bool<E>(self, _: bool) -> Result<Located, E> {
        self.leaf()
    }

    fn visit_i64<E>(self, _: i64) -> Result<Located, E> {
        self.leaf()
    }

    fn visit_u64<E>(self, _: u64) -> Result<Located, E> {
        self.leaf()
    }

    fn visit_f64<E>(self, value: f64) -> Result<Located, E> {
        Ok(Located {
            span: None,
            node: Node::Float(value),
        })
    }

    fn visit_str<E>(self, _: &str) -> Result<Located, E> {
        self.leaf()
    }

    /// A spanned value (its start, end and value), or a table: its
    /// entries, or (a date-time) toml's private key for it.
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Located, A::Error> {
        let (mut start, mut end, mut node) = (None, None, None);
        let mut entries = Vec::new();
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                START => start = Some(map.next_value::<usize>()?),
                END => end = Some(map.next_value::<usize>()?),
                VALUE => node = Some(map.next_value::<Node>()?),
                _ if key.starts_with("$__toml_private") => {
                    map.next_value::<IgnoredAny>()?;
                    node = Some(Node::Leaf);
                }
                _ => entries.push((key, map.next_value::<Located>()?)),
            }
        }
        Ok(Located {
            span: start.zip(end).map(|(start, end)| start..end),
            node: node.unwrap_or(Node::Table(entries)),
        })
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Located, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = seq.next_element::<Located>()? {
            items.push(item);
        }
        Ok(Located {
            span: None,
            node: Node::Array(items),
        })
    }
}

/// The span of the value of `text` that `path` names (`object[2].radius`,
/// `material.red.checker.scale`), or of its deepest part written. A
/// parenthesised remark in the path (`animation.viewport[0] (viewport 'v')
/// .zoom`) is not part of it; a segment that is not a key of its table
/// (`width/height`) ends the walk.
pub(super) fn value_span(text: &str, path: &str) -> Option<Range<usize>> {
    let root = Node::deserialize(toml::Deserializer::new(text)).ok()?;
    let mut node = &root;
    let mut rest = path;
    let mut found = None;
    loop {
        rest = without_remark(rest);
        let child = match node {
            Node::Leaf | Node::Float(_) => break,
            Node::Table(entries) => {
                let keys = rest.strip_prefix('.').unwrap_or(rest);
                // The longest key that ends where a segment ends: a
                // material's name may itself hold a dot.
                let Some((key, child)) = entries
                    .iter()
                    .filter(|(key, _)| {
                        keys.strip_prefix(key.as_str()).is_some_and(|after| {
                            after.is_empty() || after.starts_with(['.', '[', ' '])
                        })
                    })
                    .max_by_key(|(key, _)| key.len())
                else {
                    break;
                };
                rest = &keys[key.len()..];
                child
            }
            Node::Array(items) => {
                let Some((index, after)) = rest
                    .strip_prefix('[')
                    .and_then(|r| r.split_once(']'))
                    .and_then(|(index, after)| Some((index.parse::<usize>().ok()?, after)))
                else {
                    break;
                };
                let Some(child) = items.get(index) else {
                    break;
                };
                rest = after;
                child
            }
        };
        found = child.span.clone().or(found);
        node = &child.node;
    }
    found
}

/// A number written in a scene file that the renderer's 32-bit floats
/// cannot hold: it would turn into infinity or zero, and the error that
/// followed would report a value the file never wrote.
#[derive(Debug, PartialEq)]
pub(super) struct UnfitNumber {
    /// The field path (`camera.position[2]`).
    pub path: String,
    /// Where the number was written.
    pub span: Range<usize>,
    /// Whether it is too large, rather than too near 0.
    pub too_large: bool,
    /// Its value, for a number too long to quote.
    pub value: f64,
}

impl UnfitNumber {
    /// The message, quoting the number as `text` wrote it (a long one in
    /// scientific notation: `1e300` for 300 digits).
    pub fn message(&self, text: &str) -> String {
        let written = match text.get(self.span.clone()).map(str::trim) {
            Some(written) if written.len() <= 24 => written.to_string(),
            _ => format!("{:e}", self.value),
        };
        if self.too_large {
            format!(
                "{written} is too large: numbers in a scene are 32-bit floats, at most ±{:e}",
                f32::MAX
            )
        } else {
            format!(
                "{written} is too near 0: numbers in a scene are 32-bit floats, the smallest \
                 apart from 0 is ±{:e} (write 0 for zero)",
                f32::MIN_POSITIVE
            )
        }
    }
}

/// The first float of `text` (in the order written) that a 32-bit float
/// cannot hold; None when all fit or the text does not parse (the parse
/// error is then the one to report).
pub(super) fn first_unfit_number(text: &str) -> Option<UnfitNumber> {
    let root = Node::deserialize(toml::Deserializer::new(text)).ok()?;
    let mut unfit = Vec::new();
    collect_unfit(&root, None, &mut String::new(), &mut unfit);
    unfit.into_iter().min_by_key(|number| number.span.start)
}

fn collect_unfit(
    node: &Node,
    span: Option<&Range<usize>>,
    path: &mut String,
    out: &mut Vec<UnfitNumber>,
) {
    let mut visit = |path: &mut String, segment: String, child: &Located| {
        let length = path.len();
        path.push_str(&segment);
        collect_unfit(&child.node, child.span.as_ref().or(span), path, out);
        path.truncate(length);
    };
    match node {
        Node::Leaf => {}
        &Node::Float(value) => {
            let magnitude = value.abs();
            // Infinity and NaN are written as such (`inf`, `nan`): the
            // field's own check names them.
            let too_large = magnitude.is_finite() && magnitude > f64::from(f32::MAX);
            let too_small = magnitude != 0.0 && magnitude < f64::from(f32::MIN_POSITIVE);
            if let (true, Some(span)) = (too_large || too_small, span) {
                out.push(UnfitNumber {
                    path: path.clone(),
                    span: span.clone(),
                    too_large,
                    value,
                });
            }
        }
        Node::Table(entries) => {
            for (key, child) in entries {
                let dot = if path.is_empty() { "" } else { "." };
                visit(path, format!("{dot}{key}"), child);
            }
        }
        Node::Array(items) => {
            for (index, child) in items.iter().enumerate() {
                visit(path, format!("[{index}]"), child);
            }
        }
    }
}

/// `rest` without a leading ` (remark)`.
fn without_remark(rest: &str) -> &str {
    rest.strip_prefix(" (")
        .and_then(|r| r.split_once(')'))
        .map_or(rest, |(_, after)| after)
}

#[cfg(test)]
mod tests {
    use super::value_span;

    /// The line (1-based) `path`'s span starts on.
    fn line(text: &str, path: &str) -> Option<usize> {
        value_span(text, path).map(|span| text[..span.start].matches('\n').count() + 1)
    }

    #[test]
    fn paths_find_the_line_of_their_deepest_written_part() {
        let text = "[camera]\nfov = 60\nposition = [\n  0,\n  1,\n  5,\n]\n\
                    [material.\"a.b\"]\nchecker = { colors = [[0, 0, 0], [1, 1, 1]], scale = 2 }\n\
                    [[object]]\ntype = \"sphere\"\n[[object]]\ntype = \"sphere\"\nradius = -1\n\
                    [animation]\nwhen = 1979-05-27\n[[animation.viewport]]\nzoom = 0\n";
        for (path, expected) in [
            ("camera.fov", Some(2)),
            ("camera.position", Some(3)),
            ("camera.position.y", Some(3)),
            ("camera.pitch", Some(1)),
            ("material.a.b.checker.scale", Some(9)),
            ("object[1].radius", Some(14)),
            ("object[0].radius", Some(10)),
            ("light[0].position", None),
            ("animation.when", Some(16)),
            ("animation.viewport[0] (viewport 'v').zoom", Some(18)),
            ("animation.viewport[0].zoom/rotate/translate", Some(17)),
            ("render.width", None),
        ] {
            assert_eq!(line(text, path), expected, "{path}");
        }
        assert_eq!(line("[camera\n", "camera"), None);
    }

    #[test]
    fn numbers_a_32_bit_float_cannot_hold_are_found_where_written() {
        let text = "[camera]\nfov = 60.0\nposition = [0, 1e-30, 5]\n[[object]]\n\
                    radius = 1e-300\n[[object]]\nradius = -1e39\n";
        let unfit = super::first_unfit_number(text).expect("an unfit number");
        assert_eq!(unfit.path, "object[0].radius");
        assert!(!unfit.too_large);
        assert_eq!(&text[unfit.span.clone()], "1e-300");
        assert!(unfit.message(text).starts_with("1e-300 is too near 0"));

        let text = "[render]\nambient = [0.1, 0.1, 1000000000000000000000000000000000000000.0]\n";
        let unfit = super::first_unfit_number(text).expect("an unfit number");
        assert_eq!(unfit.path, "render.ambient[2]");
        assert!(unfit.too_large);
        assert!(unfit.message(text).starts_with("1e39 is too large"));
        assert!(unfit.message(text).ends_with("at most ±3.4028235e38"));

        for fits in [
            "a = 3.4e38\nb = -1.2e-38\nc = 0.0\nd = inf\ne = nan\nf = 7",
            "a = [",
        ] {
            assert_eq!(super::first_unfit_number(fits), None, "{fits}");
        }
    }
}
