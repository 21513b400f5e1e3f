//! NumPy `.npz` archives: a zip file of `.npy` members (`np.savez(path, dual=a)` writes the
//! member `dual.npy`). A member *stored* without compression (`np.savez`) is a plain `.npy` at
//! a known offset of the archive, read in pieces like a `.npy` file ([`super::npy::Npy`]); a
//! *deflated* member (`np.savez_compressed`) cannot be read in pieces, and is refused with the
//! way out.
//!
//! Only what locating a member needs is read: the end-of-central-directory record (its last
//! 22 bytes, or further back past a comment; the zip64 record when the archive is one), the
//! central directory (name, method, sizes, local-header offset of every member, with the zip64
//! extra field NumPy writes) and the member's local header (its name and extra lengths).

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;

use crate::error::CromError;

/// A member of an archive: where its bytes are and how they are stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    /// Its name in the archive (e.g. `dual.npy`).
    pub name: String,
    /// 0: stored; 8: deflated.
    pub method: u16,
    /// Offset of its data in the archive.
    pub offset: u64,
    /// Its size in the archive.
    pub size: u64,
}

const EOCD: u32 = 0x0605_4b50;
const EOCD64_LOCATOR: u32 = 0x0706_4b50;
const CENTRAL: u32 = 0x0201_4b50;
const LOCAL: u32 = 0x0403_4b50;

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap_or([0; 8]))
}

/// The members of the archive `path`.
pub fn members(path: &Path) -> Result<Vec<Member>, CromError> {
    let bad = |m: String| {
        CromError::input(path, "the .npz archive", m, "write it again with numpy.savez (or store the arrays in HDF5)")
    };
    let file = File::open(path).map_err(|e| bad(format!("cannot be opened: {e}")))?;
    let len = file.metadata().map(|m| m.len()).map_err(|e| bad(format!("cannot be read: {e}")))?;
    let read = |at: u64, n: usize| -> Result<Vec<u8>, CromError> {
        let mut b = vec![0u8; n];
        file.read_exact_at(&mut b, at).map_err(|e| bad(format!("is cut short: {e}")))?;
        Ok(b)
    };
    // The end record: 22 bytes plus a comment of at most 65 535.
    let tail_len = len.min(22 + 65_535) as usize;
    let tail = read(len - tail_len as u64, tail_len)?;
    let at = (0..tail_len.saturating_sub(21))
        .rev()
        .find(|&i| u32_at(&tail, i) == EOCD)
        .ok_or_else(|| bad("is not a zip archive (no end-of-central-directory record)".into()))?;
    let eocd_pos = len - tail_len as u64 + at as u64;
    let (mut entries, mut cd_size, mut cd_offset) =
        (u64::from(u16_at(&tail, at + 10)), u64::from(u32_at(&tail, at + 12)), u64::from(u32_at(&tail, at + 16)));
    if (entries == 0xFFFF || cd_offset == 0xFFFF_FFFF) && eocd_pos >= 20 {
        let loc = read(eocd_pos - 20, 20)?;
        if u32_at(&loc, 0) == EOCD64_LOCATOR {
            let rec = read(u64_at(&loc, 8), 56)?;
            entries = u64_at(&rec, 32);
            cd_size = u64_at(&rec, 40);
            cd_offset = u64_at(&rec, 48);
        }
    }
    if cd_offset.saturating_add(cd_size) > len || cd_size > 1 << 30 {
        return Err(bad("has a central directory beyond its end".into()));
    }
    let cd = read(cd_offset, cd_size as usize)?;
    let mut out = Vec::new();
    let mut p = 0usize;
    for _ in 0..entries {
        if p + 46 > cd.len() || u32_at(&cd, p) != CENTRAL {
            return Err(bad("has a damaged central directory".into()));
        }
        let method = u16_at(&cd, p + 10);
        let mut size = u64::from(u32_at(&cd, p + 20));
        let mut usize_ = u64::from(u32_at(&cd, p + 24));
        let (name_len, extra_len, comment_len) =
            (usize::from(u16_at(&cd, p + 28)), usize::from(u16_at(&cd, p + 30)), usize::from(u16_at(&cd, p + 32)));
        let mut local = u64::from(u32_at(&cd, p + 42));
        let end = p + 46 + name_len + extra_len;
        if end > cd.len() {
            return Err(bad("has a damaged central directory".into()));
        }
        let name = String::from_utf8_lossy(&cd[p + 46..p + 46 + name_len]).into_owned();
        // The zip64 extra field: the 64-bit values of the fields that hold 0xFFFFFFFF, in order.
        let mut e = p + 46 + name_len;
        while e + 4 <= end {
            let (id, n) = (u16_at(&cd, e), usize::from(u16_at(&cd, e + 2)));
            if id == 1 {
                let mut q = e + 4;
                for field in [&mut usize_, &mut size, &mut local] {
                    if *field == 0xFFFF_FFFF && q + 8 <= e + 4 + n {
                        *field = u64_at(&cd, q);
                        q += 8;
                    }
                }
            }
            e += 4 + n;
        }
        let head = read(local, 30)?;
        if u32_at(&head, 0) != LOCAL {
            return Err(bad(format!("has a damaged local header for {name}")));
        }
        let offset = local + 30 + u64::from(u16_at(&head, 26)) + u64::from(u16_at(&head, 28));
        if offset.saturating_add(size) > len {
            return Err(bad(format!("has member {name} beyond its end")));
        }
        out.push(Member { name, method, offset, size });
        p = end + comment_len;
    }
    Ok(out)
}

/// The member `name` (with or without `.npy`) of the archive `path` named in the scene as
/// `field`, if it is stored uncompressed; otherwise an error naming the archive, the member
/// and the fix.
pub fn stored_member(path: &Path, name: &str, field: &str) -> Result<Member, CromError> {
    let all = members(path)?;
    let want = if name.ends_with(".npy") { name.to_string() } else { format!("{name}.npy") };
    let want = want.trim_start_matches('/').to_string();
    let Some(m) = all.iter().find(|m| m.name == want) else {
        let names: Vec<&str> = all.iter().map(|m| m.name.trim_end_matches(".npy")).collect();
        return Err(CromError::input(
            path,
            format!("member {name}"),
            format!("is not in the archive (it holds: {})", names.join(", ")),
            format!("correct {field}.dataset (the keyword given to np.savez)"),
        ));
    };
    match m.method {
        0 => Ok(m.clone()),
        method => Err(CromError::input(
            path,
            format!("member {name}"),
            format!(
                "is compressed (zip method {method}, as np.savez_compressed writes), so it cannot be read in pieces"
            ),
            "save the arrays with np.savez (uncompressed) instead of np.savez_compressed, or as HDF5 datasets",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stored zip archive written by hand, as Python's zipfile writes one: a local header per
    /// member, then the central directory and its end record.
    pub(crate) fn write_zip(path: &Path, members: &[(&str, &[u8], u16)]) {
        let mut out: Vec<u8> = Vec::new();
        let mut central: Vec<u8> = Vec::new();
        for (name, data, method) in members {
            let local = out.len() as u32;
            out.extend(LOCAL.to_le_bytes());
            out.extend([20, 0, 0, 0]);
            out.extend(method.to_le_bytes());
            out.extend([0u8; 8]); // time, date, crc (not checked here)
            out.extend((data.len() as u32).to_le_bytes());
            out.extend((data.len() as u32).to_le_bytes());
            out.extend((name.len() as u16).to_le_bytes());
            out.extend(0u16.to_le_bytes());
            out.extend(name.as_bytes());
            out.extend(*data);
            central.extend(CENTRAL.to_le_bytes());
            central.extend([20, 0, 20, 0, 0, 0]);
            central.extend(method.to_le_bytes());
            central.extend([0u8; 8]);
            central.extend((data.len() as u32).to_le_bytes());
            central.extend((data.len() as u32).to_le_bytes());
            central.extend((name.len() as u16).to_le_bytes());
            central.extend([0u8; 12]); // extra, comment, disk, attributes
            central.extend(local.to_le_bytes());
            central.extend(name.as_bytes());
        }
        let cd_offset = out.len() as u32;
        out.extend(&central);
        out.extend(EOCD.to_le_bytes());
        out.extend([0u8; 4]);
        out.extend((members.len() as u16).to_le_bytes());
        out.extend((members.len() as u16).to_le_bytes());
        out.extend((central.len() as u32).to_le_bytes());
        out.extend(cd_offset.to_le_bytes());
        out.extend(0u16.to_le_bytes());
        std::fs::write(path, out).expect("write zip");
    }

    #[test]
    fn members_are_found_at_their_offsets() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.npz");
        write_zip(&p, &[("a.npy", b"first", 0), ("dual.npy", b"second!", 0), ("z.npy", b"xx", 8)]);
        let m = stored_member(&p, "dual", "model.external.dual").expect("stored");
        let mut b = vec![0u8; m.size as usize];
        File::open(&p).expect("open").read_exact_at(&mut b, m.offset).expect("read");
        assert_eq!(b, b"second!");
        let e = stored_member(&p, "z", "model.external.dual").expect_err("deflated");
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("np.savez_compressed"), "{e}");
        let e = stored_member(&p, "nothere", "model.external.dual").expect_err("missing");
        assert!(e.to_string().contains("a, dual, z"), "{e}");
    }
}
