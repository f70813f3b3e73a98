//! Measured time series in, result files out.
//!
//! Reading: [`read_record`] (with a [`RecordSpec`]) turns a measurement file of any [`Format`]
//! (CSV, NumPy `.npy` and `.npz`, MATLAB level-5 MAT-files), told from its first bytes, into a
//! [`TimeSeries`]: a uniformly sampled record of an input and an output with absolute sample
//! times, its columns chosen by name. [`read_csv`] (with a [`CsvSpec`]) and [`read_npy`] (with
//! an [`NpySpec`], columns by index) read one format each. Writing: [`CsvWriter`], [`write_timeseries_csv`] and
//! [`write_json_atomic`] write complete files or nothing, and [`OutputDir`] stages all files of a
//! run and moves them into place only when the run succeeds, refusing to overwrite unless asked.
//! Every failure is a [`DataError`] whose message names the file, line and column.
//!
//! # The measured-data format (CSV)
//!
//! The project's format is a CSV file with header `t,f,x`: time `t` in s, applied force `f` in N
//! (the input), position `x` in m (the output), one row per sample. Extra columns are allowed and
//! ignored; the column order is free. [`CsvSpec::default`] reads exactly this; other files name
//! their columns in the spec, or give a sample rate instead of a time column.
//!
//! Precisely, a file is read as follows.
//! - Text is UTF-8 (ASCII is UTF-8); a leading byte-order mark is ignored. Lines end in `\n`,
//!   `\r\n` or a lone `\r`. Line numbers in messages are 1-based and count every line of the file.
//! - Blank lines, and lines whose first non-blank character is the comment character (`#` by
//!   default), are skipped anywhere. There are no end-of-line comments. A header written as a
//!   comment (as `numpy.savetxt(..., header=...)` does) is therefore not seen as a header.
//! - The first remaining line is the header of column names. Names may be quoted (`"V1"`, with
//!   `""` for a quote inside). A header of numbers only is an error: every file needs names.
//! - Cells are separated by `,` by default, or `;`, tab, runs of blanks, or a separator guessed
//!   from the header ([`Delimiter`]). Blanks around cells are ignored; a quoted cell may contain
//!   the separator. A requested column missing from a one-cell header that contains `;`, a tab
//!   or `,` is reported as a file in another separator, naming the delimiter to set.
//! - Every data row has as many cells as the header has names. A trailing separator on the
//!   header and the rows (`"V1","V2",` then `0.0057756,0.0093978,`) makes an empty last column,
//!   which is dropped.
//! - The used cells (time, input, output) are decimal numbers as Rust's `f64` parser reads them
//!   (`1.5`, `-2e-3`, `.5`), and must be finite: `NaN`, `inf` and overflow like `1e400` are errors.
//!   Cells of other columns are not parsed. The decimal mark is `.` always.
//! - Times, when given, are absolute, strictly increasing and uniform: each step is within the
//!   relative tolerance ([`CsvSpec::time_tolerance`], default 1e-6) of the median step, plus the
//!   rounding of differencing two stored times. The series' `dt` is
//!   `(t_last - t_first) / (n - 1)`. With a sample rate `fs` instead, `t_k = start + k / fs`.
//! - At least [`CsvSpec::min_samples`] rows (never fewer than 2) are required.
//!
//! # Binary formats
//!
//! - `.npy`: a 2-D little-endian `float64` or `float32` array in C order, one row per sample;
//!   its columns are named by [`RecordSpec::columns`] or answer to `"0"`, `"1"`, ...
//!   ([`read_npy`] takes 0-based indices).
//! - `.npz` (`numpy.savez`, stored, or `savez_compressed`, deflated; ZIP64 headers read): each
//!   member is an `.npy` array named by its member name without `.npy`. A vector (`(n,)`,
//!   `(n, 1)`, `(1, n)`) is one column; a matrix is used through [`RecordSpec::matrix`] and
//!   [`RecordSpec::columns`].
//! - MAT-files of level 5 (MATLAB `save -v6`/`-v7`, `scipy.io.savemat`), plain or with
//!   `miCOMPRESSED` elements, either byte order: real numeric variables of every class (double,
//!   single, 8- to 64-bit integers; 64-bit values beyond 2^53 are refused as inexact), vectors
//!   or matrices as for `.npz`. Cells, structs, strings, sparse, complex and N-D arrays are
//!   named as unreadable when asked for. Version 7.3 files are HDF5 and are refused with the
//!   advice to save with `-v7`: no well-kept pure-Rust HDF5 reader exists.
//!
//! Binary values are widened exactly to `f64`; messages give 0-based rows. Whatever the format,
//! the same checks follow: finite values, one value per sample in every used column, strictly
//! increasing and uniform times (float32 times at their own rounding).
//!
//! # Written files
//!
//! CSV output is comma-separated with a one-line header and `\n` line ends. Numbers are written
//! in the shortest form that reads back to the identical `f64` (`0.0057756`, `1e-300`); non-finite
//! values as `NaN`, `inf`, `-inf`. [`write_timeseries_csv`] writes header `t,<names>`, so a
//! series written with columns `f` and `x` is again in the measured-data format.
//!
//! # Example
//!
//! ```
//! use htfid_data::{read_csv, write_timeseries_csv, CsvSpec};
//!
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("run.csv");
//! let t: Vec<f64> = (0..100).map(|k| 10.0 + k as f64 * 1e-3).collect();
//! let f: Vec<f64> = t.iter().map(|&t| (50.0 * t).sin()).collect();
//! let x: Vec<f64> = t.iter().map(|&t| 1e-3 * (50.0 * t).cos()).collect();
//! write_timeseries_csv(&path, &t, &[("f", &f), ("x", &x)])?;
//!
//! let series = read_csv(&path, &CsvSpec::default())?;
//! assert_eq!(series.len(), 100);
//! assert!((series.sample_rate() - 1000.0).abs() < 1e-6);
//! assert_eq!(series.output(), &x[..]); // bit-exact round trip
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod csv_read;
mod error;
mod mat;
mod npy;
mod outdir;
mod record;
mod series;
mod write;
mod zip;

pub use csv_read::{read_csv, CsvSpec, Delimiter, TimeSource};
pub use error::{missing_samples, ColumnId, DataError, Location};
pub use npy::{read_npy, NpySpec};
pub use outdir::OutputDir;
pub use record::{read_record, Format, RecordSpec};
pub use series::{TimeSeries, DEFAULT_TIME_TOLERANCE};
pub use write::{write_json_atomic, write_timeseries_csv, CsvWriter};
