//! MATLAB MAT-files, level 5 (what `save -v6` and `save -v7` write, and `scipy.io.savemat`):
//! real numeric matrices of any numeric class, in either byte order, plain or inside
//! `miCOMPRESSED` (zlib) elements. Version 7.3 files are HDF5 containers and are refused with
//! the way out; cells, structs, strings, sparse and complex arrays are listed as unreadable.
//!
//! Layout (MathWorks, "MAT-File Format", level 5): a 128-byte header whose last 4 bytes are the
//! version and the endian mark `IM` (little-endian writer) or `MI`; then data elements, each an
//! 8-byte tag (type, byte count) and data padded to 8 bytes, or a 4-byte "small" tag with up to
//! 4 bytes of data. A variable is an `miMATRIX` element: array flags (class), dimensions, name,
//! real part (stored in any numeric type, e.g. a double matrix of small integers as `miUINT8`).

use std::path::Path;

use crate::error::DataError;
use crate::record::Variable;

const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;

const HDF5_SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";

/// Why the MAT reader refuses v7.3, in one place for the message and the docs.
pub(crate) const V73_ADVICE: &str = "MATLAB v7.3 MAT-files are HDF5 containers, and htfid reads \
     no HDF5 (no well-kept pure-Rust reader exists, and the build must need no system \
     libraries); save the variables with save(FILE, ..., '-v7'), which writes a level-5 \
     MAT-file htfid reads, or use scipy.io.savemat";

#[derive(Debug, Clone, Copy)]
enum Endian {
    Little,
    Big,
}

impl Endian {
    fn u32(self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        match self {
            Endian::Little => u32::from_le_bytes(a),
            Endian::Big => u32::from_be_bytes(a),
        }
    }
}

/// A variable the file holds but htfid cannot read, with the reason.
#[derive(Debug)]
pub(crate) struct Skipped {
    pub name: String,
    pub why: String,
}

/// Whether `bytes` start like a MAT-file (level 5 or 7.3).
pub(crate) fn looks_like_mat(bytes: &[u8]) -> bool {
    bytes.starts_with(b"MATLAB ")
}

/// The readable variables of a MAT-file and the unreadable ones.
pub(crate) fn parse_mat(
    bytes: &[u8],
    path: &Path,
) -> Result<(Vec<Variable>, Vec<Skipped>), DataError> {
    let bad = |reason: String| DataError::MatFormat {
        path: path.to_path_buf(),
        reason,
    };
    let unsupported = |what: String| DataError::MatUnsupported {
        path: path.to_path_buf(),
        what,
    };
    if bytes.starts_with(b"MATLAB 7.3") || bytes.get(512..520) == Some(HDF5_SIGNATURE) {
        return Err(unsupported(V73_ADVICE.to_owned()));
    }
    if bytes.len() < 128 {
        return Err(bad("shorter than the 128-byte header".to_owned()));
    }
    let endian = match &bytes[126..128] {
        b"IM" => Endian::Little,
        b"MI" => Endian::Big,
        _ => {
            return Err(unsupported(
                "no level-5 endian mark at byte 126 (a level-4 MAT-file?); save it with \
                 save(FILE, ..., '-v7')"
                    .to_owned(),
            ))
        }
    };
    let mut vars = Vec::new();
    let mut skipped = Vec::new();
    let mut at = 128;
    while at + 8 <= bytes.len() {
        let (kind, data, next) = element(bytes, at, endian).map_err(&bad)?;
        match kind {
            MI_MATRIX => matrix(data, endian, &mut vars, &mut skipped).map_err(&bad)?,
            MI_COMPRESSED => {
                let inner = miniz_oxide::inflate::decompress_to_vec_zlib(data).map_err(|e| {
                    bad(format!(
                        "corrupt compressed element at byte {at} ({:?})",
                        e.status
                    ))
                })?;
                let mut i = 0;
                while i + 8 <= inner.len() {
                    let (kind, data, next) = element(&inner, i, endian).map_err(&bad)?;
                    if kind == MI_MATRIX {
                        matrix(data, endian, &mut vars, &mut skipped).map_err(&bad)?;
                    }
                    i = next;
                }
            }
            // Other top-level elements (e.g. subsystem data) carry no variables.
            _ => {}
        }
        at = next;
    }
    Ok((vars, skipped))
}

/// The element at `at`: its type, its data and where the next one starts.
fn element(b: &[u8], at: usize, endian: Endian) -> Result<(u32, &[u8], usize), String> {
    let tag = b
        .get(at..at + 8)
        .ok_or_else(|| format!("the file ends inside a tag at byte {at}"))?;
    let first = endian.u32(&tag[..4]);
    // Small data element: byte count in the upper half of the first word (in either byte
    // order), data in the second.
    let small = first >> 16;
    if small != 0 {
        let n = small as usize;
        if n > 4 {
            return Err(format!("malformed small element at byte {at}"));
        }
        return Ok((first & 0xFFFF, &tag[4..4 + n], at + 8));
    }
    let n = endian.u32(&tag[4..8]) as usize;
    let data = b
        .get(at + 8..(at + 8).saturating_add(n))
        .ok_or_else(|| format!("element at byte {at} claims {n} bytes but the file ends before"))?;
    // Compressed elements are not padded; all others are padded to 8 bytes.
    let next = if first == MI_COMPRESSED {
        at + 8 + n
    } else {
        at + 8 + n.div_ceil(8) * 8
    };
    Ok((first, data, next))
}

fn class_name(class: u32) -> &'static str {
    match class {
        1 => "a cell array",
        2 => "a struct",
        3 => "an object",
        4 => "a char array",
        5 => "a sparse matrix",
        _ => "of an unknown class",
    }
}

/// Decodes one `miMATRIX` element into `vars`, or notes in `skipped` why it cannot be read.
fn matrix(
    data: &[u8],
    endian: Endian,
    vars: &mut Vec<Variable>,
    skipped: &mut Vec<Skipped>,
) -> Result<(), String> {
    let (kind, flags, at) = element(data, 0, endian)?;
    if kind != MI_UINT32 || flags.len() < 8 {
        return Err("a matrix without array flags".to_owned());
    }
    let word = endian.u32(&flags[..4]);
    let class = word & 0xFF;
    let complex = word & 0x0800 != 0;
    let (_, dims, at) = element(data, at, endian)?;
    let dims: Vec<usize> = dims
        .chunks_exact(4)
        .map(|c| endian.u32(c) as usize)
        .collect();
    let (_, name, at) = element(data, at, endian)?;
    let name = String::from_utf8_lossy(name).into_owned();
    let skip = |why: String| Skipped {
        name: name.clone(),
        why,
    };
    if !(6..=15).contains(&class) {
        skipped.push(skip(format!("is {}", class_name(class))));
        return Ok(());
    }
    if complex {
        skipped.push(skip("is complex".to_owned()));
        return Ok(());
    }
    let &[rows, cols] = dims.as_slice() else {
        skipped.push(skip(format!(
            "has {} dimensions {dims:?}; only vectors and 2-D matrices are read",
            dims.len()
        )));
        return Ok(());
    };
    let (kind, real, _) = element(data, at, endian)?;
    let values = decode(kind, real, endian).map_err(|e| format!("variable \"{name}\": {e}"))?;
    if values.len() != rows.saturating_mul(cols) {
        return Err(format!(
            "variable \"{name}\" is {rows}x{cols} but holds {} values",
            values.len()
        ));
    }
    // MAT-files store columns one after the other (column-major), as `Variable` does.
    vars.push(Variable {
        name,
        rows,
        cols,
        data: values,
        // Single-class data carry float32 rounding; all other classes are exact in f64.
        eps: if class == 7 {
            f64::from(f32::EPSILON)
        } else {
            f64::EPSILON
        },
    });
    Ok(())
}

/// The values of a numeric element, widened exactly to `f64`.
fn decode(kind: u32, b: &[u8], endian: Endian) -> Result<Vec<f64>, String> {
    fn take<const N: usize>(b: &[u8], endian: Endian) -> impl Iterator<Item = [u8; N]> + '_ {
        b.chunks_exact(N).map(move |c| {
            let mut a = [0; N];
            a.copy_from_slice(c);
            if matches!(endian, Endian::Big) {
                a.reverse();
            }
            a
        })
    }
    // 2^53: integers beyond it have no exact f64.
    const EXACT: u64 = 1 << 53;
    Ok(match kind {
        MI_DOUBLE => take::<8>(b, endian).map(f64::from_le_bytes).collect(),
        MI_SINGLE => take::<4>(b, endian)
            .map(|a| f64::from(f32::from_le_bytes(a)))
            .collect(),
        MI_INT8 => b.iter().map(|&v| f64::from(v as i8)).collect(),
        MI_UINT8 => b.iter().map(|&v| f64::from(v)).collect(),
        MI_INT16 => take::<2>(b, endian)
            .map(|a| f64::from(i16::from_le_bytes(a)))
            .collect(),
        MI_UINT16 => take::<2>(b, endian)
            .map(|a| f64::from(u16::from_le_bytes(a)))
            .collect(),
        MI_INT32 => take::<4>(b, endian)
            .map(|a| f64::from(i32::from_le_bytes(a)))
            .collect(),
        MI_UINT32 => take::<4>(b, endian)
            .map(|a| f64::from(u32::from_le_bytes(a)))
            .collect(),
        MI_INT64 => take::<8>(b, endian)
            .map(|a| {
                let v = i64::from_le_bytes(a);
                if v.unsigned_abs() <= EXACT {
                    Ok(v as f64)
                } else {
                    Err(format!("the 64-bit integer {v} has no exact double"))
                }
            })
            .collect::<Result<_, _>>()?,
        MI_UINT64 => take::<8>(b, endian)
            .map(|a| {
                let v = u64::from_le_bytes(a);
                if v <= EXACT {
                    Ok(v as f64)
                } else {
                    Err(format!("the 64-bit integer {v} has no exact double"))
                }
            })
            .collect::<Result<_, _>>()?,
        other => return Err(format!("numeric data of unknown type {other}")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn v73_is_refused_with_the_way_out() {
        let mut bytes = b"MATLAB 7.3 MAT-file, Platform: GLNXA64".to_vec();
        bytes.resize(600, 0);
        let err = parse_mat(&bytes, Path::new("r.mat")).unwrap_err();
        assert!(err
            .to_string()
            .starts_with("r.mat: unsupported MAT-file: MATLAB v7.3 MAT-files are HDF5 containers"));
        assert!(err.to_string().contains("'-v7'"));
    }

    #[test]
    fn small_elements_and_padding() {
        // A little-endian small element: 2 bytes of type miUINT8.
        let b = [2, 0, 2, 0, 7, 9, 0, 0];
        let (kind, data, next) = element(&b, 0, Endian::Little).unwrap();
        assert_eq!((kind, data, next), (MI_UINT8, &[7u8, 9][..], 8));
        // A normal element of 3 bytes is padded to 8.
        let b = [2, 0, 0, 0, 3, 0, 0, 0, 1, 2, 3, 0, 0, 0, 0, 0];
        let (_, data, next) = element(&b, 0, Endian::Little).unwrap();
        assert_eq!((data, next), (&[1u8, 2, 3][..], 16));
    }

    #[test]
    fn big_endian_values_are_swapped() {
        let b = 1.5f64.to_be_bytes();
        assert_eq!(decode(MI_DOUBLE, &b, Endian::Big).unwrap(), vec![1.5]);
        let b = (-3i16).to_be_bytes();
        assert_eq!(decode(MI_INT16, &b, Endian::Big).unwrap(), vec![-3.0]);
    }
}
