//! CSV text from any `serde::Serialize` rows: one column per scalar field,
//! nested structs named `outer.inner`.
//!
//! A small serializer of its own rather than `serde_json::Value`, which
//! turns infinities into `null` and forgets whether a number was a float.

use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt::Display;

use serde::ser::{self, Serialize};

/// How floating-point cells are written. Non-finite values are always
/// `inf`, `-inf` or `NaN`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Floats {
    /// Rust's `{}`: the shortest text that reads back to the same value.
    Shortest,
    /// `{:.N}`: N digits after the point.
    Fixed(usize),
}

impl Floats {
    fn text<F: Display + Copy + Into<f64>>(self, v: F) -> String {
        let x: f64 = v.into();
        match self {
            _ if x.is_nan() => "NaN".to_owned(),
            _ if x.is_infinite() => if x > 0.0 { "inf" } else { "-inf" }.to_owned(),
            Floats::Shortest => v.to_string(),
            Floats::Fixed(digits) => format!("{v:.digits$}"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    #[error("cannot write CSV: column `{0}` is not in the header")]
    NotInHeader(String),
    #[error("cannot write CSV: column `{0}` appears twice")]
    DuplicateColumn(String),
    #[error("cannot write CSV: a list of records cannot go in one CSV cell (`{0}`)")]
    ListOfRecords(String),
    #[error("cannot write CSV: a row must be a struct or a map, not a single value")]
    NotARecord,
    #[error("cannot write CSV: {0}")]
    Custom(String),
}

impl ser::Error for CsvError {
    fn custom<T: Display>(msg: T) -> Self {
        CsvError::Custom(msg.to_string())
    }
}

/// `rows` as CSV text with a header line.
///
/// The header is the columns of `columns_of`, which should have every
/// optional value `Some`: a `None` struct is one empty cell under the
/// field's own name, so only a full row shows all the nested columns. Each
/// row's cells go under the header's columns by name; a `None` cell `x`
/// leaves every column `x.…` empty.
pub fn csv_text<T: Serialize>(
    rows: &[T],
    columns_of: &T,
    floats: Floats,
) -> Result<String, CsvError> {
    let header: Vec<String> = cells_of(columns_of, floats)?
        .into_iter()
        .map(|(column, _)| column)
        .collect();
    let mut index = HashMap::new();
    for (i, column) in header.iter().enumerate() {
        if index.insert(column.as_str(), i).is_some() {
            return Err(CsvError::DuplicateColumn(column.clone()));
        }
    }
    let mut text = String::new();
    push_line(&mut text, header.iter().map(String::as_str));
    for row in rows {
        let mut slots: Vec<Option<String>> = vec![None; header.len()];
        for (column, text) in cells_of(row, floats)? {
            match index.get(column.as_str()) {
                Some(&i) if slots[i].is_some() => return Err(CsvError::DuplicateColumn(column)),
                Some(&i) => slots[i] = Some(text.unwrap_or_default()),
                None if text.is_none() && has_nested(&header, &column) => {}
                None => return Err(CsvError::NotInHeader(column)),
            }
        }
        push_line(&mut text, slots.iter().map(|s| s.as_deref().unwrap_or("")));
    }
    Ok(text)
}

/// Whether `header` has columns `column.…`, nested in `column`.
/// The records of CSV `text` (as [`csv_text`] writes it) as written, each
/// without its line end: a line break inside a quoted cell belongs to its
/// record.
pub fn csv_records(text: &str) -> Vec<&str> {
    let (mut records, mut start, mut quoted) = (Vec::new(), 0, false);
    for (i, c) in text.char_indices() {
        match c {
            // A doubled quote inside a quoted cell flips twice.
            '"' => quoted = !quoted,
            '\n' if !quoted => {
                records.push(text[start..i].trim_end_matches('\r'));
                start = i + 1;
            }
            _ => {}
        }
    }
    if start < text.len() {
        records.push(&text[start..]);
    }
    records
}

fn has_nested(header: &[String], column: &str) -> bool {
    let prefix = format!("{column}.");
    header.iter().any(|h| h.starts_with(&prefix))
}

fn push_line<'a>(text: &mut String, cells: impl Iterator<Item = &'a str>) {
    for (i, cell) in cells.enumerate() {
        if i > 0 {
            text.push(',');
        }
        text.push_str(&quote(cell));
    }
    text.push('\n');
}

fn quote(cell: &str) -> Cow<'_, str> {
    if cell.contains([',', '"', '\r', '\n']) {
        Cow::Owned(format!("\"{}\"", cell.replace('"', "\"\"")))
    } else {
        Cow::Borrowed(cell)
    }
}

/// One cell of a row: its column and text, no text for `None` or unit.
type Cell = (String, Option<String>);

fn cells_of<T: Serialize>(value: &T, floats: Floats) -> Result<Vec<Cell>, CsvError> {
    let Flat::Record(fields) = value.serialize(ToFlat(floats))? else {
        return Err(CsvError::NotARecord);
    };
    let mut cells = Vec::new();
    for (key, value) in fields {
        flatten(value, key, &mut cells)?;
    }
    Ok(cells)
}

fn flatten(flat: Flat, column: String, cells: &mut Vec<Cell>) -> Result<(), CsvError> {
    let text = match flat {
        Flat::Record(fields) => {
            for (key, value) in fields {
                flatten(value, format!("{column}.{key}"), cells)?;
            }
            return Ok(());
        }
        Flat::Empty => None,
        other => Some(joined(other, &column)?),
    };
    cells.push((column, text));
    Ok(())
}

/// The text of one cell: a list's items joined by spaces.
fn joined(flat: Flat, column: &str) -> Result<String, CsvError> {
    match flat {
        Flat::Text(text) => Ok(text),
        Flat::Empty => Ok(String::new()),
        Flat::List(items) => Ok(items
            .into_iter()
            .map(|item| joined(item, column))
            .collect::<Result<Vec<_>, _>>()?
            .join(" ")),
        Flat::Record(_) => Err(CsvError::ListOfRecords(column.to_owned())),
    }
}

/// A serialized value before it is laid out in columns.
enum Flat {
    Text(String),
    /// `None` or unit.
    Empty,
    List(Vec<Flat>),
    /// Struct fields or map entries, in order.
    Record(Vec<(String, Flat)>),
}

/// The serializer: any value to a [`Flat`].
#[derive(Clone, Copy)]
struct ToFlat(Floats);

/// What the serializer's methods return.
type R = Result<Flat, CsvError>;

macro_rules! as_text {
    ($($method:ident: $ty:ty),* $(,)?) => {$(
        fn $method(self, v: $ty) -> R {
            Ok(Flat::Text(v.to_string()))
        }
    )*};
}

impl ser::Serializer for ToFlat {
    type Ok = Flat;
    type Error = CsvError;
    type SerializeSeq = ListSer;
    type SerializeTuple = ListSer;
    type SerializeTupleStruct = ListSer;
    type SerializeTupleVariant = ListSer;
    type SerializeMap = RecordSer;
    type SerializeStruct = RecordSer;
    type SerializeStructVariant = RecordSer;

    as_text!(
        serialize_bool: bool, serialize_char: char, serialize_str: &str,
        serialize_i8: i8, serialize_i16: i16, serialize_i32: i32, serialize_i64: i64,
        serialize_i128: i128, serialize_u8: u8, serialize_u16: u16, serialize_u32: u32,
        serialize_u64: u64, serialize_u128: u128,
    );

    fn serialize_f32(self, v: f32) -> R {
        Ok(Flat::Text(self.0.text(v)))
    }
    fn serialize_f64(self, v: f64) -> R {
        Ok(Flat::Text(self.0.text(v)))
    }
    fn serialize_bytes(self, v: &[u8]) -> R {
        Ok(Flat::List(
            v.iter().map(|b| Flat::Text(b.to_string())).collect(),
        ))
    }
    fn serialize_none(self) -> R {
        Ok(Flat::Empty)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> R {
        value.serialize(self)
    }
    fn serialize_unit(self) -> R {
        Ok(Flat::Empty)
    }
    fn serialize_unit_struct(self, _: &str) -> R {
        Ok(Flat::Empty)
    }
    fn serialize_unit_variant(self, _: &str, _: u32, variant: &str) -> R {
        Ok(Flat::Text(variant.to_owned()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &str, value: &T) -> R {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T>(self, _: &str, _: u32, _: &str, value: &T) -> R
    where
        T: Serialize + ?Sized,
    {
        value.serialize(self)
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<ListSer, CsvError> {
        Ok(ListSer(self, Vec::new()))
    }
    fn serialize_tuple(self, _: usize) -> Result<ListSer, CsvError> {
        Ok(ListSer(self, Vec::new()))
    }
    fn serialize_tuple_struct(self, _: &str, _: usize) -> Result<ListSer, CsvError> {
        Ok(ListSer(self, Vec::new()))
    }
    fn serialize_tuple_variant(
        self,
        _: &str,
        _: u32,
        _: &str,
        _: usize,
    ) -> Result<ListSer, CsvError> {
        Ok(ListSer(self, Vec::new()))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<RecordSer, CsvError> {
        Ok(RecordSer(self, Vec::new()))
    }
    fn serialize_struct(self, _: &str, _: usize) -> Result<RecordSer, CsvError> {
        Ok(RecordSer(self, Vec::new()))
    }
    fn serialize_struct_variant(
        self,
        _: &str,
        _: u32,
        _: &str,
        _: usize,
    ) -> Result<RecordSer, CsvError> {
        Ok(RecordSer(self, Vec::new()))
    }
}

/// Collects a sequence's or tuple's items.
struct ListSer(ToFlat, Vec<Flat>);

macro_rules! list_ser {
    ($($trait:ident: $method:ident),*) => {$(
        impl ser::$trait for ListSer {
            type Ok = Flat;
            type Error = CsvError;
            fn $method<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), CsvError> {
                self.1.push(value.serialize(self.0)?);
                Ok(())
            }
            fn end(self) -> R {
                Ok(Flat::List(self.1))
            }
        }
    )*};
}

list_ser!(
    SerializeSeq: serialize_element,
    SerializeTuple: serialize_element,
    SerializeTupleStruct: serialize_field,
    SerializeTupleVariant: serialize_field
);

/// Collects a struct's fields or a map's entries, alike: `#[serde(flatten)]`
/// turns a struct into a map.
struct RecordSer(ToFlat, Vec<(String, Flat)>);

impl ser::SerializeMap for RecordSer {
    type Ok = Flat;
    type Error = CsvError;
    /// The entry goes in now, its value when [`Self::serialize_value`] comes.
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), CsvError> {
        let Flat::Text(key) = key.serialize(self.0)? else {
            return Err(CsvError::Custom(
                "a map key must be text or a number".into(),
            ));
        };
        self.1.push((key, Flat::Empty));
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), CsvError> {
        let value = value.serialize(self.0)?;
        if let Some(entry) = self.1.last_mut() {
            entry.1 = value;
        }
        Ok(())
    }
    fn end(self) -> R {
        Ok(Flat::Record(self.1))
    }
}

macro_rules! struct_ser {
    ($($trait:ident),*) => {$(
        impl ser::$trait for RecordSer {
            type Ok = Flat;
            type Error = CsvError;
            fn serialize_field<T>(&mut self, key: &str, value: &T) -> Result<(), CsvError>
            where
                T: Serialize + ?Sized,
            {
                self.1.push((key.to_owned(), value.serialize(self.0)?));
                Ok(())
            }
            fn end(self) -> R {
                Ok(Flat::Record(self.1))
            }
        }
    )*};
}

struct_ser!(SerializeStruct, SerializeStructVariant);

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Serialize;

    #[test]
    fn records_are_split_at_line_ends_outside_quotes() {
        #[derive(Serialize)]
        struct Row {
            frame: u32,
            view: &'static str,
        }
        let rows = [
            Row {
                frame: 0,
                view: "a",
            },
            Row {
                frame: 1,
                view: "two\nlines, \"quoted\"",
            },
            Row { frame: 2, view: "" },
        ];
        let text = csv_text(&rows, &rows[0], Floats::Shortest).unwrap();
        let records = csv_records(&text);
        assert_eq!(
            records,
            [
                "frame,view",
                "0,a",
                "1,\"two\nlines, \"\"quoted\"\"\"",
                "2,"
            ]
        );
        assert_eq!(csv_records("a\r\nb"), ["a", "b"]);
    }

    #[derive(Serialize)]
    struct Point {
        x: f64,
        y: f64,
    }

    #[derive(Serialize)]
    struct Shot {
        name: &'static str,
        at: Point,
        hit: Option<Point>,
    }

    fn shot(name: &'static str, hit: Option<Point>) -> Shot {
        Shot {
            name,
            at: Point { x: 1.0, y: 2.5 },
            hit,
        }
    }

    #[test]
    fn nested_structs_are_dotted_columns_and_none_empties_them() {
        let full = shot("a", Some(Point { x: 0.0, y: -1.0 }));
        let rows = [shot("a", Some(Point { x: 3.0, y: 4.0 })), shot("b", None)];
        assert_eq!(
            csv_text(&rows, &full, Floats::Shortest).unwrap(),
            "name,at.x,at.y,hit.x,hit.y\na,1,2.5,3,4\nb,1,2.5,,\n"
        );
    }

    #[test]
    fn flattened_fields_are_inline_in_order() {
        #[derive(Serialize)]
        struct Timing {
            ms: u32,
            rays: u64,
        }
        #[derive(Serialize)]
        struct Row {
            frame: u32,
            #[serde(flatten)]
            timing: Timing,
            at: Point,
            last: bool,
        }
        let row = Row {
            frame: 7,
            timing: Timing { ms: 12, rays: 300 },
            at: Point { x: 0.5, y: 1.0 },
            last: true,
        };
        assert_eq!(
            csv_text(std::slice::from_ref(&row), &row, Floats::Shortest).unwrap(),
            "frame,ms,rays,at.x,at.y,last\n7,12,300,0.5,1,true\n"
        );
    }

    #[test]
    fn floats_shortest_fixed_and_non_finite() {
        #[derive(Serialize)]
        struct Row {
            a: f64,
            b: f64,
            c: f64,
            d: f32,
        }
        let row = Row {
            a: 0.1,
            b: f64::INFINITY,
            c: f64::NAN,
            d: 0.1,
        };
        let rows = [
            row,
            Row {
                a: 2.0 / 3.0,
                b: f64::NEG_INFINITY,
                c: 1e21,
                d: -0.0,
            },
        ];
        assert_eq!(
            csv_text(&rows, &rows[0], Floats::Shortest).unwrap(),
            "a,b,c,d\n0.1,inf,NaN,0.1\n0.6666666666666666,-inf,1000000000000000000000,-0\n"
        );
        assert_eq!(
            csv_text(&rows, &rows[0], Floats::Fixed(6)).unwrap(),
            "a,b,c,d\n0.100000,inf,NaN,0.100000\n0.666667,-inf,1000000000000000000000.000000,-0.000000\n"
        );
    }

    #[test]
    fn cells_with_commas_quotes_or_newlines_are_quoted() {
        #[derive(Serialize)]
        struct Row {
            #[serde(rename = "a,b")]
            text: String,
        }
        let rows = ["plain", "x,y", "say \"hi\"", "two\nlines", "cr\r"]
            .map(|t| Row { text: t.to_owned() });
        assert_eq!(
            csv_text(&rows, &rows[0], Floats::Shortest).unwrap(),
            "\"a,b\"\nplain\n\"x,y\"\n\"say \"\"hi\"\"\"\n\"two\nlines\"\n\"cr\r\"\n"
        );
    }

    #[test]
    fn lists_of_scalars_share_one_cell() {
        #[derive(Serialize)]
        struct Row {
            ids: Vec<u32>,
            pair: (i8, char),
        }
        let rows = [
            Row {
                ids: vec![3, 7],
                pair: (-1, 'z'),
            },
            Row {
                ids: vec![],
                pair: (0, 'a'),
            },
        ];
        assert_eq!(
            csv_text(&rows, &rows[0], Floats::Shortest).unwrap(),
            "ids,pair\n3 7,-1 z\n,0 a\n"
        );
    }

    #[test]
    fn enums_are_written_by_variant() {
        #[derive(Serialize)]
        enum Method {
            Full,
            Rsvp,
            Tiles(u32),
        }
        #[derive(Serialize)]
        struct Row {
            method: Method,
        }
        let rows = [
            Row {
                method: Method::Full,
            },
            Row {
                method: Method::Rsvp,
            },
            Row {
                method: Method::Tiles(16),
            },
        ];
        assert_eq!(
            csv_text(&rows, &rows[0], Floats::Shortest).unwrap(),
            "method\nFull\nRsvp\n16\n"
        );
    }

    #[test]
    fn a_column_not_in_the_header_is_an_error() {
        let rows = [shot("a", Some(Point { x: 1.0, y: 1.0 }))];
        let err = csv_text(&rows, &shot("h", None), Floats::Shortest).unwrap_err();
        assert!(
            matches!(&err, CsvError::NotInHeader(c) if c == "hit.x"),
            "{err}"
        );
        assert_eq!(
            err.to_string(),
            "cannot write CSV: column `hit.x` is not in the header"
        );
    }

    #[test]
    fn a_list_of_records_is_an_error() {
        #[derive(Serialize)]
        struct Row {
            points: Vec<Point>,
        }
        let row = Row {
            points: vec![Point { x: 1.0, y: 2.0 }],
        };
        let err = csv_text(std::slice::from_ref(&row), &row, Floats::Shortest).unwrap_err();
        assert_eq!(
            err.to_string(),
            "cannot write CSV: a list of records cannot go in one CSV cell (`points`)"
        );
    }
}
