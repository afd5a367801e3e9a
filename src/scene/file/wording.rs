//! serde's type errors in a user's words: `invalid type: string "x",
//! expected f32` becomes `expected a number, got the string "x"`.
//!
//! Promises: a message serde's words for types, lengths and variants are
//! recognised in is reworded (what was expected first, then what the file
//! had); any other message comes back as it was.

/// `message`, an error serde gave for the value at `field` (the path the
/// user wrote), reworded where its words are Rust's; `written` is the
/// value's text, for a message that does not say what it was.
pub(super) fn reworded(message: &str, field: &str, written: Option<&str>) -> String {
    let reworded = if let Some(rest) = message.strip_prefix("invalid type: ") {
        rest.split_once(", expected ")
            .map(|(got, expected)| (expected_words(expected, got, field), got_words(got)))
    } else if let Some(rest) = message.strip_prefix("invalid value: ") {
        rest.split_once(", expected ")
            .map(|(got, expected)| (expected_words(expected, got, field), got_words(got)))
    } else if let Some(rest) = message.strip_prefix("invalid length ") {
        rest.split_once(", expected ").map(|(count, expected)| {
            let got = match count {
                "1" => "1 value".to_string(),
                n => format!("{n} values"),
            };
            (expected_words(expected, "", field), got)
        })
    } else if let Some(rest) = message.strip_prefix("unknown variant ") {
        rest.split_once(", expected one of ").map(|(got, choices)| {
            let choices: Vec<String> = choices.split(", ").map(quoted).collect();
            (format!("one of {}", choices.join(", ")), quoted(got))
        })
    } else if message == "wanted string or table" {
        // toml's words for an enum given a value that is not a string.
        let got = written.map_or(String::new(), |text| format!(", got {text}"));
        return format!("expected a string in quotes{got}");
    } else {
        None
    };
    match reworded {
        // A number as the file wrote it (`1e30`), not as serde prints its
        // parsed value (31 digits).
        Some((expected, got))
            if message.contains(" floating point `") || message.contains(" integer `") =>
        {
            format!("expected {expected}, got {}", written.unwrap_or(&got))
        }
        Some((expected, got)) => format!("expected {expected}, got {got}"),
        None => message.to_string(),
    }
}

/// What serde's `expected` says a field takes, in words; `got` is the
/// value it was given (an integer out of range gets the range).
fn expected_words(expected: &str, got: &str, field: &str) -> String {
    let out_of_range = got.starts_with("integer `");
    match expected {
        "f32" | "f64" => "a number".into(),
        "u8" | "u16" | "u32" | "u64" | "usize" if out_of_range => {
            let max = match expected {
                "u8" => u64::from(u8::MAX),
                "u16" => u64::from(u16::MAX),
                "u32" => u64::from(u32::MAX),
                _ => u64::MAX,
            };
            format!("a whole number from 0 to {max}")
        }
        "u8" | "u16" | "u32" | "u64" | "usize" | "i8" | "i16" | "i32" | "i64" | "isize" => {
            "a whole number".into()
        }
        "a boolean" => "true or false".into(),
        "a string" | "a borrowed string" | "a character" => "a string in quotes".into(),
        "a sequence" => "an array".into(),
        "a map" | "a spanned value" => "a table".into(),
        _ if expected.starts_with("struct ") => "a table".into(),
        _ => match expected.strip_prefix("an array of length ") {
            // The pair of colours of a checker; every other fixed-length
            // array holds numbers (a point, a colour, a size).
            Some("2") if field.ends_with("checker.colors") => "an array of 2 colours".into(),
            Some(n) => format!("an array of {n} numbers"),
            None => expected.to_string(),
        },
    }
}

/// serde's description of a value the file had, in words.
fn got_words(got: &str) -> String {
    let quoted_value = |prefix: &str| {
        got.strip_prefix(prefix)
            .and_then(|v| v.strip_prefix('`'))
            .and_then(|v| v.strip_suffix('`'))
            .map(str::to_string)
    };
    if let Some(text) = got.strip_prefix("string ") {
        return format!("the string {text}");
    }
    for prefix in ["integer ", "floating point ", "boolean "] {
        if let Some(value) = quoted_value(prefix) {
            return value;
        }
    }
    match got {
        "sequence" => "an array".into(),
        "map" => "a table".into(),
        _ => got.to_string(),
    }
}

/// serde's `` `name` `` as `"name"`, the way a scene file writes it.
fn quoted(name: &str) -> String {
    format!("\"{}\"", name.trim_matches('`'))
}

#[cfg(test)]
mod tests {
    use super::reworded;

    #[test]
    fn serde_words_become_a_users() {
        for (message, field, words) in [
            (
                "invalid type: string \"wide\", expected f64",
                "camera.fov",
                "expected a number, got the string \"wide\"",
            ),
            (
                "invalid type: floating point `1.5`, expected u32",
                "render.width",
                "expected a whole number, got 1.5",
            ),
            (
                "invalid value: integer `-3`, expected u32",
                "animation.frames",
                "expected a whole number from 0 to 4294967295, got -3",
            ),
            (
                "invalid type: string \"yes\", expected a boolean",
                "object[0].smooth",
                "expected true or false, got the string \"yes\"",
            ),
            (
                "invalid type: integer `5`, expected a string",
                "object[0].name",
                "expected a string in quotes, got 5",
            ),
            (
                "invalid length 2, expected an array of length 3",
                "camera.position",
                "expected an array of 3 numbers, got 2 values",
            ),
            (
                "invalid length 1, expected an array of length 2",
                "material.a.checker.colors",
                "expected an array of 2 colours, got 1 value",
            ),
            (
                "invalid type: string \"origin\", expected an array of length 3",
                "object[0].center",
                "expected an array of 3 numbers, got the string \"origin\"",
            ),
            (
                "invalid type: integer `5`, expected a sequence",
                "object[0].vertices",
                "expected an array, got 5",
            ),
            (
                "invalid type: integer `5`, expected struct CameraDef",
                "camera",
                "expected a table, got 5",
            ),
            (
                "invalid type: sequence, expected a map",
                "material",
                "expected a table, got an array",
            ),
            (
                "unknown variant `fish`, expected one of `perspective`, `equal-angle`, `fisheye`",
                "camera.projection",
                "expected one of \"perspective\", \"equal-angle\", \"fisheye\", got \"fish\"",
            ),
            (
                "wanted string or table",
                "camera.projection",
                "expected a string in quotes, got 3",
            ),
            // Other messages stay as they were.
            (
                "missing field `position`",
                "camera",
                "missing field `position`",
            ),
            (
                "invalid array\nexpected `]`",
                "",
                "invalid array\nexpected `]`",
            ),
        ] {
            let written = (message == "wanted string or table").then_some("3");
            assert_eq!(reworded(message, field, written), words, "{message}");
        }
    }

    #[test]
    fn numbers_are_quoted_as_written() {
        let message =
            "invalid type: floating point `1000000000000000000000000000000`, expected u32";
        assert_eq!(
            reworded(message, "render.width", Some("1e30")),
            "expected a whole number, got 1e30"
        );
        assert_eq!(
            reworded(message, "render.width", None),
            "expected a whole number, got 1000000000000000000000000000000"
        );
    }
}
