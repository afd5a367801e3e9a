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

    fn visit_f64<E>(self, _: f64) -> Result<Located, E> {
        self.leaf()
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
            Node::Leaf => break,
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
}
