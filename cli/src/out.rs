//! What the tool prints: aligned columns for a person, JSON for a script (`--json`), from the
//! same rows, so the two never say different things.
//!
//! A [`Table`] prints as a header and lines padded to each column's widest cell, or as one JSON
//! array of objects keyed by the column names (lower case, spaces as `_`). A cell carries both
//! its text and its JSON value, so a number stays a number in JSON while it prints as `0x05`.

use serde_json::{Map, Value};
use std::io::Write;

/// One cell: what a person reads, what a script gets.
#[derive(Clone, Debug)]
pub struct Cell {
    text: String,
    json: Value,
}

impl Cell {
    /// A cell that prints `text` and is `json` in JSON.
    pub fn new(text: impl Into<String>, json: impl Into<Value>) -> Cell {
        Cell {
            text: text.into(),
            json: json.into(),
        }
    }
    /// An empty cell (`null` in JSON, `-` for a person).
    pub fn none() -> Cell {
        Cell::new("-", Value::Null)
    }
}

impl From<&str> for Cell {
    fn from(s: &str) -> Cell {
        Cell::new(s, s)
    }
}

impl From<String> for Cell {
    fn from(s: String) -> Cell {
        Cell::new(s.clone(), s)
    }
}

impl From<u64> for Cell {
    fn from(v: u64) -> Cell {
        Cell::new(v.to_string(), v)
    }
}

impl From<bool> for Cell {
    fn from(v: bool) -> Cell {
        Cell::new(if v { "yes" } else { "no" }, v)
    }
}

impl<T: Into<Cell>> From<Option<T>> for Cell {
    fn from(v: Option<T>) -> Cell {
        v.map_or_else(Cell::none, Into::into)
    }
}

/// A node-ID as `0x05` for a person and `5` for a script.
pub fn node_cell(id: u8) -> Cell {
    Cell::new(format!("{id:#04x}"), id)
}

/// Rows under named columns.
#[derive(Debug, Default)]
pub struct Table {
    cols: Vec<String>,
    rows: Vec<Vec<Cell>>,
}

impl Table {
    /// A table with these column names.
    pub fn new(cols: &[&str]) -> Table {
        Table {
            cols: cols.iter().map(|c| (*c).to_string()).collect(),
            rows: Vec::new(),
        }
    }
    /// Adds a row (missing cells are empty, extra ones dropped).
    pub fn row(&mut self, mut cells: Vec<Cell>) {
        cells.resize_with(self.cols.len(), Cell::none);
        self.rows.push(cells);
    }
    /// True if it has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
    /// The rows as JSON objects.
    pub fn to_json(&self) -> Value {
        Value::Array(
            self.rows
                .iter()
                .map(|r| {
                    let mut m = Map::new();
                    for (c, cell) in self.cols.iter().zip(r) {
                        m.insert(json_key(c), cell.json.clone());
                    }
                    Value::Object(m)
                })
                .collect(),
        )
    }
    /// The table as aligned text: a header line, then one line per row.
    pub fn to_text(&self) -> String {
        let mut widths: Vec<usize> = self.cols.iter().map(|c| c.chars().count()).collect();
        for r in &self.rows {
            for (w, cell) in widths.iter_mut().zip(r) {
                *w = (*w).max(cell.text.chars().count());
            }
        }
        let line = |cells: Vec<&str>| {
            let mut s = String::new();
            for (i, (c, w)) in cells.iter().zip(&widths).enumerate() {
                if i + 1 == cells.len() {
                    s.push_str(c);
                } else {
                    s.push_str(&format!("{c:<w$}  "));
                }
            }
            s.trim_end().to_string()
        };
        let mut out = line(self.cols.iter().map(String::as_str).collect());
        out.push('\n');
        for r in &self.rows {
            out.push_str(&line(r.iter().map(|c| c.text.as_str()).collect()));
            out.push('\n');
        }
        out
    }
    /// Prints the table as `--json` asks.
    pub fn print(&self, json: bool) {
        if json {
            emit_json(&self.to_json());
        } else {
            print_text(&self.to_text());
        }
    }
}

/// A column name as a JSON key: lower case, `_` for spaces and slashes.
fn json_key(col: &str) -> String {
    col.to_lowercase()
        .chars()
        .map(|c| if c == ' ' || c == '/' { '_' } else { c })
        .collect()
}

/// Prints one JSON value on a line of its own.
pub fn emit_json(v: &Value) {
    print_text(&format!("{v}\n"));
}

/// Prints text to standard output; a closed pipe (`| head`) ends the output quietly.
pub fn print_text(s: &str) {
    let mut out = std::io::stdout().lock();
    if out
        .write_all(s.as_bytes())
        .and_then(|()| out.flush())
        .is_err()
    {
        std::process::exit(0);
    }
}

/// Prints a result: `text` for a person, `json` for a script.
pub fn result(json: bool, text: &str, value: Value) {
    if json {
        emit_json(&value);
    } else {
        print_text(&format!("{text}\n"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_line_up_and_json_keeps_types() {
        let mut t = Table::new(&["node", "state", "heard bus 1"]);
        t.row(vec![node_cell(5), "operational".into(), true.into()]);
        t.row(vec![node_cell(0x7f), "stopped".into()]);
        assert_eq!(
            t.to_text(),
            "node  state        heard bus 1\n\
             0x05  operational  yes\n\
             0x7f  stopped      -\n"
        );
        assert_eq!(
            t.to_json().to_string(),
            r#"[{"node":5,"state":"operational","heard_bus_1":true},{"node":127,"state":"stopped","heard_bus_1":null}]"#
        );
    }
}
