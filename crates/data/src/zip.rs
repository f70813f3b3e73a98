//! The part of the ZIP format that `.npz` files use: members stored or deflated, ZIP64 sizes
//! and offsets (NumPy writes every member with ZIP64 extra fields), no encryption, one disk.
//! A reader of our own keeps the build free of the `zip` crate, whose current releases need a
//! newer Rust than this workspace's minimum; inflating is `miniz_oxide`'s (pure Rust).

use std::path::Path;

use crate::error::DataError;

/// One member of an archive, decompressed and checked against its CRC-32.
#[derive(Debug)]
pub(crate) struct Member {
    pub name: String,
    pub data: Vec<u8>,
}

const EOCD: u32 = 0x0605_4b50;
const EOCD64_LOCATOR: u32 = 0x0706_4b50;
const EOCD64: u32 = 0x0606_4b50;
const CENTRAL: u32 = 0x0201_4b50;
const LOCAL: u32 = 0x0403_4b50;

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    b.get(at..at + 2).map(|s| u16::from_le_bytes([s[0], s[1]]))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    b.get(at..at + 8).map(|s| {
        let mut a = [0; 8];
        a.copy_from_slice(s);
        u64::from_le_bytes(a)
    })
}

/// Every member of the ZIP archive `bytes` (the file `path`), in central-directory order.
pub(crate) fn read_members(bytes: &[u8], path: &Path) -> Result<Vec<Member>, DataError> {
    let bad = |reason: String| DataError::ZipFormat {
        path: path.to_path_buf(),
        reason,
    };
    let truncated = || bad("the file ends inside a header (truncated?)".to_owned());
    // The end-of-central-directory record is 22 bytes plus a comment of up to 64 KiB.
    let lowest = bytes.len().saturating_sub(22 + usize::from(u16::MAX));
    let eocd = (lowest..=bytes.len().saturating_sub(22))
        .rev()
        .find(|&at| u32_at(bytes, at) == Some(EOCD))
        .ok_or_else(|| bad("no end-of-central-directory record".to_owned()))?;
    let mut count = u64::from(u16_at(bytes, eocd + 10).ok_or_else(truncated)?);
    let mut dir_offset = u64::from(u32_at(bytes, eocd + 16).ok_or_else(truncated)?);
    if count == 0xFFFF || dir_offset == 0xFFFF_FFFF {
        let locator = eocd.checked_sub(20).ok_or_else(truncated)?;
        if u32_at(bytes, locator) != Some(EOCD64_LOCATOR) {
            return Err(bad("ZIP64 sizes without a ZIP64 locator".to_owned()));
        }
        let at = usize::try_from(u64_at(bytes, locator + 8).ok_or_else(truncated)?)
            .map_err(|_| truncated())?;
        if u32_at(bytes, at) != Some(EOCD64) {
            return Err(bad("the ZIP64 end record is missing".to_owned()));
        }
        count = u64_at(bytes, at + 32).ok_or_else(truncated)?;
        dir_offset = u64_at(bytes, at + 48).ok_or_else(truncated)?;
    }
    let mut at = usize::try_from(dir_offset).map_err(|_| truncated())?;
    let mut members = Vec::new();
    for _ in 0..count {
        if u32_at(bytes, at) != Some(CENTRAL) {
            return Err(bad(format!("no central-directory entry at byte {at}")));
        }
        let flags = u16_at(bytes, at + 8).ok_or_else(truncated)?;
        let method = u16_at(bytes, at + 10).ok_or_else(truncated)?;
        let crc = u32_at(bytes, at + 16).ok_or_else(truncated)?;
        let mut packed = u64::from(u32_at(bytes, at + 20).ok_or_else(truncated)?);
        let mut size = u64::from(u32_at(bytes, at + 24).ok_or_else(truncated)?);
        let name_len = usize::from(u16_at(bytes, at + 28).ok_or_else(truncated)?);
        let extra_len = usize::from(u16_at(bytes, at + 30).ok_or_else(truncated)?);
        let comment_len = usize::from(u16_at(bytes, at + 32).ok_or_else(truncated)?);
        let mut local = u64::from(u32_at(bytes, at + 42).ok_or_else(truncated)?);
        let name_bytes = bytes
            .get(at + 46..at + 46 + name_len)
            .ok_or_else(truncated)?;
        let name = String::from_utf8_lossy(name_bytes).into_owned();
        let extra = bytes
            .get(at + 46 + name_len..at + 46 + name_len + extra_len)
            .ok_or_else(truncated)?;
        // ZIP64 extra field: the 8-byte values of exactly those fields saturated above, in
        // the order size, packed size, local header offset.
        let mut e = 0;
        while e + 4 <= extra.len() {
            let id = u16_at(extra, e).ok_or_else(truncated)?;
            let len = usize::from(u16_at(extra, e + 2).ok_or_else(truncated)?);
            if id == 1 {
                let mut p = e + 4;
                for field in [&mut size, &mut packed, &mut local] {
                    if *field == 0xFFFF_FFFF {
                        *field = u64_at(extra, p).ok_or_else(truncated)?;
                        p += 8;
                    }
                }
            }
            e += 4 + len;
        }
        at += 46 + name_len + extra_len + comment_len;

        if flags & 1 != 0 {
            return Err(DataError::ZipUnsupported {
                path: path.to_path_buf(),
                what: format!("member \"{name}\" is encrypted"),
            });
        }
        let local = usize::try_from(local).map_err(|_| truncated())?;
        if u32_at(bytes, local) != Some(LOCAL) {
            return Err(bad(format!("member \"{name}\": no local header")));
        }
        let start = local
            + 30
            + usize::from(u16_at(bytes, local + 26).ok_or_else(truncated)?)
            + usize::from(u16_at(bytes, local + 28).ok_or_else(truncated)?);
        let packed = usize::try_from(packed).map_err(|_| truncated())?;
        let size = usize::try_from(size).map_err(|_| truncated())?;
        let raw = bytes
            .get(start..start.saturating_add(packed))
            .ok_or_else(|| bad(format!("member \"{name}\" runs past the end of the file")))?;
        let data = match method {
            0 => raw.to_vec(),
            8 => miniz_oxide::inflate::decompress_to_vec_with_limit(raw, size).map_err(|e| {
                bad(format!(
                    "member \"{name}\": corrupt deflate data ({:?})",
                    e.status
                ))
            })?,
            other => {
                return Err(DataError::ZipUnsupported {
                    path: path.to_path_buf(),
                    what: format!(
                        "member \"{name}\" uses compression method {other}; only stored (0) and \
                         deflated (8) members are read, as numpy.savez and savez_compressed write"
                    ),
                })
            }
        };
        if data.len() != size || crc32(&data) != crc {
            return Err(bad(format!(
                "member \"{name}\" fails its size or CRC-32 check (the file is damaged)"
            )));
        }
        members.push(Member { name, data });
    }
    Ok(members)
}

/// CRC-32 (IEEE, reflected), as ZIP stores it.
fn crc32(data: &[u8]) -> u32 {
    let mut table = [0u32; 256];
    for (i, slot) in table.iter_mut().enumerate() {
        let mut c = i as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
        *slot = c;
    }
    let mut crc = !0u32;
    for &b in data {
        crc = table[((crc ^ u32::from(b)) & 0xFF) as usize] ^ (crc >> 8);
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_of_the_standard_check_string() {
        // The check value every CRC-32/ISO-HDLC implementation publishes.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn not_a_zip_is_named() {
        let err = read_members(b"t,f,x\n", Path::new("a.npz")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "a.npz: not a valid .npz (ZIP) file: no end-of-central-directory record"
        );
    }
}
