//! What a table is made of: its columns (name, kind, unit, meaning) and the cells of a
//! row. Shared by the table writer and reader ([`super::table`]) and the Parquet side
//! ([`super::parquet_sink`]); re-exported from `table`.

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A float (DOUBLE).
    Float,
    /// A count (INT64).
    Int,
    /// A stable body id: any u64 (INT64 annotated unsigned in Parquet, its bits kept).
    Id,
    /// A word (UTF8).
    Text,
}

/// One column of an output table, with its unit and meaning (printed by
/// `agglo schema --outputs`, listed in docs/outputs.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column {
    /// The column's name in the table.
    pub name: &'static str,
    /// What its values are (float, integer, id, text).
    pub kind: Kind,
    /// SI unit, `-` for a pure number.
    pub unit: &'static str,
    /// What it holds, in a line.
    pub doc: &'static str,
}

/// A float column.
pub const fn float(name: &'static str, unit: &'static str, doc: &'static str) -> Column {
    Column {
        name,
        kind: Kind::Float,
        unit,
        doc,
    }
}

/// An integer column (counts and ids).
pub const fn int(name: &'static str, unit: &'static str, doc: &'static str) -> Column {
    Column {
        name,
        kind: Kind::Int,
        unit,
        doc,
    }
}

/// A stable-id column (any u64).
pub const fn id(name: &'static str, unit: &'static str, doc: &'static str) -> Column {
    Column {
        name,
        kind: Kind::Id,
        unit,
        doc,
    }
}

/// A text column.
pub const fn text(name: &'static str, doc: &'static str) -> Column {
    Column {
        name,
        kind: Kind::Text,
        unit: "-",
        doc,
    }
}

/// One value of a row, of its column's kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cell<'a> {
    /// A float.
    F(f64),
    /// An integer.
    I(i64),
    /// A stable id.
    U(u64),
    /// Text.
    S(&'a str),
}
