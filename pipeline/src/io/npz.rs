//! NumPy `.npz` archives: a zip file of `.npy` members (`np.savez(path, dual=a)` writes the
//! member `dual.npy`). A member *stored* without compression (`np.savez`) is a plain `.npy` at
//! a known offset of the archive, read in pieces like a `.npy` file ([`super::npy::Npy`]). A
//! *deflated* member (`np.savez_compressed`) cannot be read in pieces where it lies: it is
//! inflated, block by block and checked against its CRC-32, into a temporary file that is
//! unlinked as soon as it is open (so nothing is left behind and memory stays one block),
//! and read in pieces from there.
//!
//! Only what locating a member needs is read: the end-of-central-directory record (its last
//! 22 bytes, or further back past a comment; the zip64 record when the archive is one), the
//! central directory (name, method, sizes, local-header offset of every member, with the zip64
//! extra field NumPy writes) and the member's local header (its name and extra lengths).

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;

use super::npy::Npy;
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
    /// Its size once inflated (= `size` when stored).
    pub unpacked: u64,
    /// CRC-32 of its inflated bytes.
    pub crc: u32,
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
        let crc = u32_at(&cd, p + 16);
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
        out.push(Member { name, method, offset, size, unpacked: usize_, crc });
        p = end + comment_len;
    }
    Ok(out)
}

/// The member `name` (with or without `.npy`) of the archive `path` named in the scene as
/// `field`, or an error naming the archive, the member and the fix.
pub fn member(path: &Path, name: &str, field: &str) -> Result<Member, CromError> {
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
    Ok(m.clone())
}

/// Zip's method number of a deflated member.
const DEFLATED: u16 = 8;

/// The member `name` of the archive `path` (named in the scene as `field`) as a `.npy` array
/// read in pieces: where it lies when stored, from an unlinked temporary file (under the
/// system's temporary directory, `TMPDIR`) when deflated.
pub fn open_member(path: &Path, name: &str, field: &str) -> Result<Npy, CromError> {
    let m = member(path, name, field)?;
    match m.method {
        0 => Npy::open_at(path, m.offset, m.size),
        DEFLATED => inflate(path, &m, name),
        method => Err(CromError::input(
            path,
            format!("member {name}"),
            format!("is stored with zip method {method}, which this reader does not know (np.savez stores, np.savez_compressed deflates)"),
            "save the arrays with np.savez or np.savez_compressed, or as HDF5 datasets",
        )),
    }
}

/// Inflate the deflated member `m` of `path` into a temporary file, check its size and
/// CRC-32 against the central directory, open it as a `.npy` and unlink it.
fn inflate(path: &Path, m: &Member, name: &str) -> Result<Npy, CromError> {
    use std::io::{Read, Seek, SeekFrom, Write};
    let damaged = |why: String| {
        CromError::input(
            path,
            format!("member {name}"),
            format!("cannot be decompressed: {why}"),
            "write the archive again with numpy.savez_compressed or numpy.savez, or store the arrays in HDF5",
        )
    };
    let mut src = File::open(path).map_err(|e| CromError::io(path, "opening the archive", e))?;
    src.seek(SeekFrom::Start(m.offset)).map_err(|e| CromError::io(path, "reading the archive", e))?;
    let mut inflater = flate2::read::DeflateDecoder::new(std::io::BufReader::new(src.take(m.size)));
    let tmp = std::env::temp_dir().join(format!(
        "crom-inflated-{}-{}-{}.npy",
        std::process::id(),
        m.offset,
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos())
    ));
    let written = (|| -> Result<u64, CromError> {
        let mut out = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp).map_err(|e| {
            CromError::io(
                &tmp,
                "creating a temporary file for an inflated .npz member (set TMPDIR to a writable directory)",
                e,
            )
        })?;
        let mut crc = flate2::Crc::new();
        let mut buf = vec![0u8; 1 << 20];
        let mut total = 0u64;
        loop {
            let n = inflater.read(&mut buf).map_err(|e| damaged(e.to_string()))?;
            if n == 0 {
                break;
            }
            total += n as u64;
            if total > m.unpacked {
                return Err(damaged(format!(
                    "it inflates to more than the {} bytes its directory entry gives",
                    m.unpacked
                )));
            }
            crc.update(&buf[..n]);
            out.write_all(&buf[..n]).map_err(|e| {
                CromError::io(&tmp, "writing an inflated .npz member (is the temporary directory full? set TMPDIR)", e)
            })?;
        }
        if total != m.unpacked {
            return Err(damaged(format!("it inflates to {total} bytes, its directory entry gives {}", m.unpacked)));
        }
        if crc.sum() != m.crc {
            return Err(damaged(format!(
                "CRC-32 {:08x} of the inflated bytes, the archive says {:08x}",
                crc.sum(),
                m.crc
            )));
        }
        out.flush().map_err(|e| CromError::io(&tmp, "writing an inflated .npz member", e))?;
        Ok(total)
    })();
    let opened = written.and_then(|size| Npy::open_at(&tmp, 0, size));
    // Unlinked whatever happened: an open array keeps its bytes until it is dropped.
    let _ = std::fs::remove_file(&tmp);
    Ok(opened?.shown_as(path))
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

    /// One member whose central entry gives `crc` and the inflated size `unpacked`.
    fn write_zip_sized(path: &Path, name: &str, data: &[u8], method: u16, crc: u32, unpacked: u32) {
        write_zip(path, &[(name, data, method)]);
        let mut b = std::fs::read(path).expect("read zip");
        let cd = b.windows(4).rposition(|w| w == CENTRAL.to_le_bytes()).expect("central entry");
        b[cd + 16..cd + 20].copy_from_slice(&crc.to_le_bytes());
        b[cd + 24..cd + 28].copy_from_slice(&unpacked.to_le_bytes());
        std::fs::write(path, b).expect("write zip");
    }

    #[test]
    fn members_are_found_at_their_offsets() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let p = dir.path().join("a.npz");
        write_zip(&p, &[("a.npy", b"first", 0), ("dual.npy", b"second!", 0), ("z.npy", b"xx", 9)]);
        let m = member(&p, "dual", "model.external.dual").expect("stored");
        let mut b = vec![0u8; m.size as usize];
        File::open(&p).expect("open").read_exact_at(&mut b, m.offset).expect("read");
        assert_eq!(b, b"second!");
        let e = open_member(&p, "z", "model.external.dual").expect_err("method 9");
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("zip method 9"), "{e}");
        let e = member(&p, "nothere", "model.external.dual").expect_err("missing");
        assert!(e.to_string().contains("a, dual, z"), "{e}");
    }

    /// A deflated member (flate2's encoder standing in for zlib's) reads as the array it holds,
    /// under the archive's name, and leaves no temporary file; a member whose CRC or size does
    /// not match its directory entry is refused naming the member.
    #[test]
    fn a_deflated_member_is_inflated_and_checked() {
        use std::io::Write;
        let values: Vec<f64> = (0..5000).map(|i| (i as f64 * 0.37).sin()).collect();
        let plain = crate::io::npy::tests::npy_bytes(&[values.len()], false, &values);
        let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(&plain).expect("deflate");
        let packed = enc.finish().expect("deflate");
        let mut crc = flate2::Crc::new();
        crc.update(&plain);
        let dir = crate::scratch::tempdir().expect("tempdir");
        let p = dir.path().join("c.npz");
        let zip = |crc: u32, unpacked: u32| write_zip_sized(&p, "dual.npy", &packed, DEFLATED, crc, unpacked);
        let before: Vec<_> =
            std::fs::read_dir(std::env::temp_dir()).expect("tmp").flatten().map(|e| e.file_name()).collect();
        zip(crc.sum(), plain.len() as u32);
        let a = open_member(&p, "dual", "model.external.dual").expect("inflated");
        assert_eq!(a.shape, vec![values.len()]);
        assert_eq!(a.read_all().expect("read"), values);
        let left: Vec<_> = std::fs::read_dir(std::env::temp_dir())
            .expect("tmp")
            .flatten()
            .map(|e| e.file_name())
            .filter(|n| {
                n.to_string_lossy().starts_with(&format!("crom-inflated-{}-", std::process::id()))
                    && !before.contains(n)
            })
            .collect();
        assert!(left.is_empty(), "left behind: {left:?}");
        zip(crc.sum() ^ 1, plain.len() as u32);
        let e = open_member(&p, "dual", "model.external.dual").expect_err("crc");
        assert!(e.to_string().contains("member dual") && e.to_string().contains("CRC-32"), "{e}");
        zip(crc.sum(), plain.len() as u32 - 8);
        let e = open_member(&p, "dual", "model.external.dual").expect_err("size");
        assert!(e.to_string().contains("more than"), "{e}");
    }
}
