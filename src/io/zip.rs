//! A minimal zip container (PKWARE APPNOTE), enough for X3P files: reading finds the
//! end-of-central-directory record, walks the central directory, and takes each entry's
//! data after its local header; methods 0 (stored) and 8 (deflate) are supported, and
//! every entry is checked against its CRC-32 and size. No zip64, encryption or
//! multi-disk archives (each is a clear error). Writing stores or deflates each entry,
//! whichever is smaller, with a fixed timestamp so equal inputs give equal bytes.

use std::fmt;

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ZipError(pub String);

impl fmt::Display for ZipError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ZipError {}

fn fail<T>(message: impl Into<String>) -> Result<T, ZipError> {
    Err(ZipError(message.into()))
}

const LOCAL_HEADER: u32 = 0x0403_4b50;
const CENTRAL_HEADER: u32 = 0x0201_4b50;
const END_OF_CENTRAL_DIRECTORY: u32 = 0x0605_4b50;
const ZIP64_LOCATOR: u32 = 0x0706_4b50;
const STORED: u16 = 0;
const DEFLATED: u16 = 8;
/// 1980-01-01 00:00, the earliest MS-DOS date.
const DOS_DATE: u16 = (1 << 5) | 1;

/// One file in an archive, as the central directory describes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ZipEntry {
    pub name: String,
    pub method: u16,
    flags: u16,
    pub crc32: u32,
    pub compressed_size: u32,
    pub size: u32,
    local_header_offset: u32,
}

/// An archive read from memory.
#[derive(Debug)]
pub struct ZipArchive<'a> {
    bytes: &'a [u8],
    pub entries: Vec<ZipEntry>,
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

impl<'a> ZipArchive<'a> {
    pub fn parse(bytes: &'a [u8]) -> Result<ZipArchive<'a>, ZipError> {
        let truncated = || ZipError("the central directory is truncated".into());
        // The end record is the last 22 bytes plus a comment of up to 65535 bytes.
        let lowest = bytes.len().saturating_sub(22 + 0xFFFF);
        let Some(end) = (lowest..=bytes.len().saturating_sub(22))
            .rev()
            .find(|&at| u32_at(bytes, at) == Some(END_OF_CENTRAL_DIRECTORY))
        else {
            return fail("no end-of-central-directory record: not a zip archive, or truncated");
        };
        if end >= 20 && u32_at(bytes, end - 20) == Some(ZIP64_LOCATOR) {
            return fail("zip64 archives are not supported");
        }
        let field16 = |off: usize| u16_at(bytes, end + off).ok_or_else(truncated);
        let field32 = |off: usize| u32_at(bytes, end + off).ok_or_else(truncated);
        let (disk, cd_disk) = (field16(4)?, field16(6)?);
        let (count, cd_size, cd_offset) = (field16(10)?, field32(12)?, field32(16)?);
        if count == 0xFFFF || cd_size == 0xFFFF_FFFF || cd_offset == 0xFFFF_FFFF {
            return fail("zip64 archives are not supported");
        }
        if disk != 0 || cd_disk != 0 {
            return fail("multi-disk archives are not supported");
        }
        let mut entries = Vec::with_capacity(count as usize);
        let mut at = cd_offset as usize;
        for _ in 0..count {
            if u32_at(bytes, at) != Some(CENTRAL_HEADER) {
                return fail(format!("no central directory entry at byte {at}"));
            }
            let f16 = |off: usize| u16_at(bytes, at + off).ok_or_else(truncated);
            let f32 = |off: usize| u32_at(bytes, at + off).ok_or_else(truncated);
            let (name_len, extra_len, comment_len) =
                (f16(28)? as usize, f16(30)? as usize, f16(32)? as usize);
            let name = bytes
                .get(at + 46..at + 46 + name_len)
                .ok_or_else(truncated)?;
            let entry = ZipEntry {
                name: String::from_utf8_lossy(name).into_owned(),
                flags: f16(8)?,
                method: f16(10)?,
                crc32: f32(16)?,
                compressed_size: f32(20)?,
                size: f32(24)?,
                local_header_offset: f32(42)?,
            };
            if [entry.compressed_size, entry.size, entry.local_header_offset].contains(&0xFFFF_FFFF)
            {
                return fail(format!("`{}`: zip64 entries are not supported", entry.name));
            }
            entries.push(entry);
            at += 46 + name_len + extra_len + comment_len;
        }
        Ok(ZipArchive { bytes, entries })
    }

    /// The entry called `name` (exactly, else ignoring ASCII case as openGPS does).
    pub fn find(&self, name: &str) -> Option<&ZipEntry> {
        let name = name.trim_start_matches("./");
        (self.entries.iter().find(|e| e.name == name)).or_else(|| {
            self.entries
                .iter()
                .find(|e| e.name.eq_ignore_ascii_case(name))
        })
    }

    /// The contents of `name`, checked against its size and CRC-32; `None` if absent.
    pub fn read(&self, name: &str) -> Result<Option<Vec<u8>>, ZipError> {
        self.find(name).map(|e| self.read_entry(e)).transpose()
    }

    pub fn read_entry(&self, entry: &ZipEntry) -> Result<Vec<u8>, ZipError> {
        let name = &entry.name;
        if entry.flags & 1 != 0 {
            return fail(format!("`{name}` is encrypted"));
        }
        let at = entry.local_header_offset as usize;
        if u32_at(self.bytes, at) != Some(LOCAL_HEADER) {
            return fail(format!("`{name}`: no local header at byte {at}"));
        }
        let lengths = (u16_at(self.bytes, at + 26), u16_at(self.bytes, at + 28));
        let (Some(name_len), Some(extra_len)) = lengths else {
            return fail(format!("`{name}`: truncated local header"));
        };
        let start = at + 30 + name_len as usize + extra_len as usize;
        let Some(stored) = self
            .bytes
            .get(start..start + entry.compressed_size as usize)
        else {
            return fail(format!(
                "`{name}`: the data runs past the end of the archive"
            ));
        };
        let data = match entry.method {
            STORED => stored.to_vec(),
            DEFLATED => {
                miniz_oxide::inflate::decompress_to_vec_with_limit(stored, entry.size as usize)
                    .map_err(|e| ZipError(format!("`{name}`: cannot inflate: {e}")))?
            }
            m => {
                return fail(format!(
                    "`{name}`: compression method {m} is not supported (only 0 stored and 8 deflate)"
                ));
            }
        };
        if data.len() != entry.size as usize {
            return fail(format!(
                "`{name}`: {} bytes where the directory says {}",
                data.len(),
                entry.size
            ));
        }
        let crc = crc32fast::hash(&data);
        if crc != entry.crc32 {
            return fail(format!(
                "`{name}`: CRC-32 mismatch (stored {:08x}, computed {crc:08x}): the archive is corrupted",
                entry.crc32
            ));
        }
        Ok(data)
    }
}

/// A zip archive holding `files` (name, contents) in order, each deflated when that
/// makes it smaller.
pub fn write_zip(files: &[(&str, &[u8])]) -> Result<Vec<u8>, ZipError> {
    let too_big = |what: &str| ZipError(format!("{what} is too large for a zip without zip64"));
    if files.len() >= 0xFFFF {
        return Err(too_big("the file count"));
    }
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, data) in files {
        let size = u32::try_from(data.len()).map_err(|_| too_big(name))?;
        let deflated = miniz_oxide::deflate::compress_to_vec(data, 6);
        let (method, stored): (u16, &[u8]) = if deflated.len() < data.len() {
            (DEFLATED, &deflated)
        } else {
            (STORED, data)
        };
        let offset = u32::try_from(out.len()).map_err(|_| too_big("the archive"))?;
        let name_len = u16::try_from(name.len()).map_err(|_| too_big(name))?;
        // Fields shared by the local and the central header, from "version needed".
        let mut common = Vec::with_capacity(26);
        common.extend(20u16.to_le_bytes()); // version needed: 2.0 (deflate)
        common.extend(0x0800u16.to_le_bytes()); // flags: names are UTF-8
        common.extend(method.to_le_bytes());
        common.extend(0u16.to_le_bytes()); // time 00:00:00
        common.extend(DOS_DATE.to_le_bytes());
        common.extend(crc32fast::hash(data).to_le_bytes());
        common.extend((stored.len() as u32).to_le_bytes());
        common.extend(size.to_le_bytes());
        common.extend(name_len.to_le_bytes());
        common.extend(0u16.to_le_bytes()); // extra field length

        out.extend(LOCAL_HEADER.to_le_bytes());
        out.extend(&common);
        out.extend(name.as_bytes());
        out.extend(stored);

        central.extend(CENTRAL_HEADER.to_le_bytes());
        central.extend(20u16.to_le_bytes()); // version made by: 2.0, MS-DOS attributes
        central.extend(&common);
        central.extend([0u8; 6]); // comment length, disk number, internal attributes
        central.extend(0u32.to_le_bytes()); // external attributes
        central.extend(offset.to_le_bytes());
        central.extend(name.as_bytes());
    }
    let cd_offset = u32::try_from(out.len()).map_err(|_| too_big("the archive"))?;
    let cd_size = central.len() as u32;
    out.extend(central);
    out.extend(END_OF_CENTRAL_DIRECTORY.to_le_bytes());
    out.extend([0u8; 4]); // this disk, disk with the central directory
    out.extend((files.len() as u16).to_le_bytes());
    out.extend((files.len() as u16).to_le_bytes());
    out.extend(cd_size.to_le_bytes());
    out.extend(cd_offset.to_le_bytes());
    out.extend(0u16.to_le_bytes()); // comment length
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes deflate cannot shrink (xorshift).
    fn noise(n: usize) -> Vec<u8> {
        let mut state = 0x9E37_79B9_u32;
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                (state >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn round_trips_stored_and_deflated_entries() {
        let text = "repetitive text ".repeat(100);
        let noise = noise(200);
        let files: [(&str, &[u8]); 3] = [
            ("main.xml", text.as_bytes()),
            ("bindata/data.bin", &noise),
            ("empty", b""),
        ];
        let bytes = write_zip(&files).unwrap();
        let archive = ZipArchive::parse(&bytes).unwrap();
        assert_eq!(archive.entries.len(), 3);
        assert_eq!(archive.entries[0].method, DEFLATED);
        assert_eq!(archive.entries[1].method, STORED);
        for (name, data) in files {
            assert_eq!(archive.read(name).unwrap().unwrap(), data, "{name}");
        }
        assert_eq!(archive.read("MAIN.XML").unwrap().unwrap(), text.as_bytes());
        assert_eq!(archive.read("missing").unwrap(), None);
        // Known CRC-32 of "123456789" (the check value of the IEEE polynomial).
        let check = write_zip(&[("c", b"123456789")]).unwrap();
        assert_eq!(
            ZipArchive::parse(&check).unwrap().entries[0].crc32,
            0xCBF4_3926
        );
    }

    #[test]
    fn corruption_is_detected() {
        let data = noise(256);
        let mut bytes = write_zip(&[("bindata/data.bin", &data)]).unwrap();
        let at = 30 + "bindata/data.bin".len() + 100;
        bytes[at] ^= 0x40;
        let archive = ZipArchive::parse(&bytes).unwrap();
        assert_eq!(archive.entries[0].method, STORED);
        let e = archive.read("bindata/data.bin").unwrap_err();
        assert!(e.0.contains("CRC-32 mismatch"), "{e}");
        assert!(ZipArchive::parse(b"not a zip").is_err());
        assert!(ZipArchive::parse(&bytes[..bytes.len() - 5]).is_err());
        let mut short = write_zip(&[("x", &data[..])]).unwrap();
        let n = short.len();
        short.drain(40..n - 60);
        assert!(ZipArchive::parse(&short).and_then(|a| a.read("x")).is_err());
    }

    #[test]
    fn zip64_is_refused_clearly() {
        let mut bytes = write_zip(&[("x", b"abc")]).unwrap();
        let n = bytes.len();
        bytes[n - 12..n - 8].copy_from_slice(&[0xFF; 4]);
        let e = ZipArchive::parse(&bytes).unwrap_err();
        assert!(e.0.contains("zip64"), "{e}");
    }
}
