//! A bounds pre-check of a binary USD crate file (`.usdc`) before `openusd` opens it.
//!
//! `openusd` 0.6 sizes its buffers from the counts the file states (`vec![0; count]`, then a
//! read) while it reads the six structural sections at open time (TOKENS, STRINGS, FIELDS,
//! FIELDSETS, PATHS, SPECS). A corrupt count (the fuzzer found 4.4 TB) makes that allocation
//! fail, and a failed allocation aborts the process: no `catch_unwind` turns it into an error.
//! This walks the same reads in the same order and checks every count against what the file
//! can hold before the reader allocates for it:
//!
//! * a compressed block's stated size against the bytes left in the file;
//! * the size it decompresses to against LZ4's largest ratio (255:1), and a count of encoded
//!   integers (at least two bits each) against the block that holds them;
//! * a plain array's bytes against the bytes left.
//!
//! Whatever the walk cannot read (past the end, an older format version) is left to the
//! reader, which fails on the same read before it allocates. Value arrays read later, per
//! attribute, are not covered (fuzz/known-crashes and docs/fuzzing.md).

use crate::error::{Error, Result};
use std::path::Path;

/// LZ4's largest expansion of a block (its output over its input), with room for the frame.
const LZ4_MAX_RATIO: u64 = 255;
const LZ4_SLACK: u64 = 64;

/// The sections `openusd` reads at open time, in its order.
const SECTIONS: [&str; 6] = ["TOKENS", "STRINGS", "FIELDS", "FIELDSETS", "PATHS", "SPECS"];

/// Why the walk stopped without a verdict: the reader will fail on the same read.
struct Unreadable;

struct Walk<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    section: &'static str,
}

impl Walk<'_> {
    fn u64(&mut self) -> std::result::Result<u64, Unreadable> {
        let end = self.pos.checked_add(8).ok_or(Unreadable)?;
        let b = self.bytes.get(self.pos..end).ok_or(Unreadable)?;
        self.pos += 8;
        Ok(u64::from_le_bytes(b.try_into().expect("eight bytes")))
    }

    fn left(&self) -> u64 {
        self.bytes.len().saturating_sub(self.pos) as u64
    }

    fn corrupt(&self, what: String) -> Error {
        Error::invalid(
            self.path,
            format!(
                "the USD crate file's {} section {what}; the file ({} bytes) cannot hold that: it \
                 is truncated or corrupt (re-export it, or convert it with `usdcat -o file.usda`)",
                self.section,
                self.bytes.len()
            ),
        )
    }

    /// A compressed block (`u64` size, then the bytes) the reader decompresses into a buffer
    /// of `out_bytes`; `out_bytes` must fit what the block can expand to.
    fn compressed(&mut self, out_bytes: u64) -> Result<std::result::Result<(), Unreadable>> {
        let Ok(size) = self.u64() else {
            return Ok(Err(Unreadable));
        };
        if size > self.left() {
            return Err(self.corrupt(format!(
                "states a compressed block of {size} bytes with {} left",
                self.left()
            )));
        }
        if out_bytes > size.saturating_mul(LZ4_MAX_RATIO).saturating_add(LZ4_SLACK) {
            return Err(self.corrupt(format!(
                "expects {out_bytes} bytes from a compressed block of {size}"
            )));
        }
        self.pos += size as usize;
        Ok(Ok(()))
    }

    /// `count` integers coded at two bits or more each, in one compressed block (the
    /// reader's `read_encoded_ints`).
    fn encoded_ints(&mut self, count: u64) -> Result<std::result::Result<(), Unreadable>> {
        if count == 0 {
            // The reader still reads the (empty) block.
            return self.compressed(0);
        }
        // Two bits per integer: a quarter byte each.
        self.compressed(count.div_ceil(4))
    }
}

/// `Err` where a structural count of the crate file `bytes` exceeds what the file can hold.
pub fn check(path: &Path, bytes: &[u8]) -> Result<()> {
    match walk(path, bytes) {
        Ok(Ok(())) | Ok(Err(Unreadable)) => Ok(()),
        Err(e) => Err(e),
    }
}

macro_rules! readable {
    ($e:expr) => {
        match $e {
            Ok(v) => v,
            Err(Unreadable) => return Ok(Err(Unreadable)),
        }
    };
}

fn walk(path: &Path, bytes: &[u8]) -> Result<std::result::Result<(), Unreadable>> {
    let mut w = Walk {
        path,
        bytes,
        pos: 0,
        section: "TOC",
    };
    if !bytes.starts_with(b"PXR-USDC") || bytes.len() < 32 {
        return Ok(Err(Unreadable));
    }
    let version = (bytes[8], bytes[9], bytes[10]);
    if version < (0, 4, 0) {
        // The reader does not read these formats at all (a clean error, or a caught panic).
        return Ok(Err(Unreadable));
    }
    w.pos = 16;
    let toc = readable!(w.u64());
    w.pos = usize::try_from(toc).unwrap_or(usize::MAX);
    let count = readable!(w.u64());
    if count == 0 || count >= 64 {
        return Ok(Err(Unreadable)); // the reader rejects it itself
    }
    let mut sections = Vec::new();
    for _ in 0..count {
        let name_end = readable!(w.pos.checked_add(16).ok_or(Unreadable));
        let name = readable!(bytes.get(w.pos..name_end).ok_or(Unreadable));
        let end = name.iter().position(|&c| c == 0).unwrap_or(16);
        let name = String::from_utf8_lossy(&name[..end]).into_owned();
        w.pos += 16;
        let start = readable!(w.u64());
        let _size = readable!(w.u64());
        sections.push((name, start));
    }
    for section in SECTIONS {
        let Some(&(_, start)) = sections.iter().find(|(n, _)| n == section) else {
            continue;
        };
        w.section = section;
        w.pos = usize::try_from(start).unwrap_or(usize::MAX);
        match section {
            "TOKENS" => {
                let _count = readable!(w.u64());
                let uncompressed = readable!(w.u64());
                readable!(w.compressed(uncompressed)?);
            }
            "STRINGS" => {
                let count = readable!(w.u64());
                if count.saturating_mul(4) > w.left() {
                    return Err(w.corrupt(format!("lists {count} strings")));
                }
            }
            "FIELDS" => {
                let count = readable!(w.u64());
                readable!(w.encoded_ints(count)?);
                // Then one 8-byte value rep per field, compressed.
                readable!(w.compressed(count.saturating_mul(8))?);
            }
            "FIELDSETS" => {
                let count = readable!(w.u64());
                readable!(w.encoded_ints(count)?);
            }
            "PATHS" => {
                // The path table is allocated from this count before anything else is read;
                // the coded paths that fill it follow.
                let paths = readable!(w.u64());
                let limit = w.left().saturating_mul(4 * LZ4_MAX_RATIO);
                if paths > limit {
                    return Err(w.corrupt(format!("lists {paths} paths")));
                }
                let coded = readable!(w.u64());
                for _ in 0..3 {
                    readable!(w.encoded_ints(coded)?);
                }
            }
            "SPECS" => {
                let count = readable!(w.u64());
                for _ in 0..3 {
                    readable!(w.encoded_ints(count)?);
                }
            }
            _ => unreachable!("SECTIONS lists only these"),
        }
    }
    Ok(Ok(()))
}
