//! Tables laid out like a paper's, with the published numbers beside ours: the layout both
//! kinds of suite declare with `[[table]]` (cells name what ran; the report fills them).

use crate::base::SafeName;
use crate::base::name::RESERVED_TABLE_IDS;
use serde::Deserialize;

/// The pseudo-metric a cell names (`objective:optimizer@fit time [s]`) to show the wall
/// seconds of a trial: median and interval over trials, like a metric.
pub const FIT_TIME: &str = "fit time [s]";

/// A table laid out like one in a paper, with its published numbers beside ours:
/// rows x columns of cells `objective:optimizer` (or `objective:optimizer@metric`).
///
/// ```toml
/// [[table]]
/// id = "table3.2"
/// title = "Table 3.2: RMS error of Bouc-Wen fits [mm]"
/// value = "train RMSE [mm]"          # default for cells without @metric; omit: the value
///                                    # (`@fit time [s]`: wall seconds per trial)
/// columns = ["GA", "MSGA"]
/// rows = [
///   { label = "1 Hz", cells = ["bw-1hz:GA", "bw-1hz:MSGA"], seed = [0.0145, 0.0066] },
/// ]
/// ```
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PaperTable {
    /// Names `tables/<id>.md` and `.tex`.
    #[serde(deserialize_with = "table_id")]
    pub id: SafeName,
    pub title: String,
    #[serde(default)]
    pub value: Option<String>,
    #[serde(default)]
    pub note: Option<String>,
    /// Who the reference numbers are from (default "seed").
    #[serde(default)]
    pub reference: Option<String>,
    pub columns: Vec<String>,
    pub rows: Vec<PaperRow>,
}

/// A table's `id`, checked as it is read (so the message points at its line): a name, and
/// not one of a built-in table.
fn table_id<'de, D: serde::Deserializer<'de>>(d: D) -> Result<SafeName, D::Error> {
    let s = String::deserialize(d)?;
    SafeName::not_reserved(&s, RESERVED_TABLE_IDS)
        .map_err(|why| serde::de::Error::custom(format!("table id {s:?} {why}")))
}

/// One row of a [`PaperTable`].
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PaperRow {
    pub label: String,
    pub cells: Vec<String>,
    /// The reference numbers, one per column (nan where there is none).
    #[serde(default)]
    pub seed: Vec<f64>,
}

/// A parsed cell reference of a [`PaperTable`].
#[derive(Debug, Clone, PartialEq)]
pub struct CellRef {
    pub objective: String,
    pub optimizer: String,
    pub metric: Option<String>,
}

impl CellRef {
    /// Parses `objective:optimizer[@metric]`.
    pub fn parse(s: &str) -> Option<CellRef> {
        let (cell, metric) = match s.split_once('@') {
            Some((c, m)) => (c, Some(m.trim().to_string())),
            None => (s, None),
        };
        let (o, p) = cell.split_once(':')?;
        Some(CellRef {
            objective: o.trim().into(),
            optimizer: p.trim().into(),
            metric,
        })
    }
}

impl PaperTable {
    /// Checks that every row has one cell, and one published value if any, per column.
    pub fn check_shape(&self) -> std::result::Result<(), String> {
        let n = self.columns.len();
        for row in &self.rows {
            if row.cells.len() != n {
                return Err(format!(
                    "row `{}` has {} cells for {n} columns",
                    row.label,
                    row.cells.len()
                ));
            }
            if !row.seed.is_empty() && row.seed.len() != n {
                return Err(format!(
                    "row `{}` has {} seed values for {n} columns",
                    row.label,
                    row.seed.len()
                ));
            }
        }
        Ok(())
    }
}
