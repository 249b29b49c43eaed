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
//! reader, which fails on the same read before it allocates. Array values, read later per
//! attribute, are checked too: every array rep in FIELDS, its element count against the bytes
//! after it, and the count-prefixed values (vectors of tokens, strings, paths, dictionaries,
//! ...) and list ops, and time samples: their times array and each sample's value as values of
//! their own.

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
    /// Dictionary entries read so far (`check_dictionary`).
    entries: std::cell::Cell<u64>,
}

/// The little-endian count of `width` bytes (4 or 8) at `pos`, and the bytes left after it;
/// `None` past the end.
fn count_at(bytes: &[u8], pos: usize, width: usize) -> Option<(u64, u64)> {
    let end = pos.checked_add(width)?;
    let mut b = [0u8; 8];
    b[..width].copy_from_slice(bytes.get(pos..end)?);
    Some((u64::from_le_bytes(b), (bytes.len() - end) as u64))
}

impl Walk<'_> {
    fn u64(&mut self) -> std::result::Result<u64, Unreadable> {
        let (v, _) = count_at(self.bytes, self.pos, 8).ok_or(Unreadable)?;
        self.pos += 8;
        Ok(v)
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

/// Value types (the crate file's type numbers) stored as a `u64` count and then the entries:
/// path vector, token vector, variant selection map, layer offset vector, string vector,
/// relocates. The reader takes them by type, whatever the rep's array flag says.
const COUNTED: [u64; 6] = [40, 41, 45, 49, 50, 58];
/// The dictionary's type number: a count, then per entry a key, a jump and a value rep that
/// the reader reads as a value of its own (recursing into nested dictionaries).
const DICTIONARY: u64 = 31;
/// Deepest nesting of values in values (dictionaries in dictionaries, time samples in them)
/// accepted: the reader recurses once per level, and a dictionary that jumps back to itself
/// never ends. Real layers nest a few levels (`customData`, `assetInfo`).
const MAX_VALUE_DEPTH: u32 = 32;
/// The double vector's type number: read like an array of doubles.
const DOUBLE_VECTOR: u64 = 48;
/// The time samples' type number.
const TIME_SAMPLES: u64 = 46;

/// List-op value types and the bytes of one stored item (`0`: items of varying size, read
/// one by one: only the first list's count is checked): token, string, path, reference, int,
/// int64, uint, uint64, unregistered-value and payload list ops.
const LIST_OPS: [(u64, u64); 10] = [
    (32, 4),
    (33, 4),
    (34, 4),
    (35, 0),
    (36, 4),
    (37, 8),
    (38, 4),
    (39, 8),
    (54, 4),
    (55, 0),
];

/// A list op at `payload`: a header byte, then each list it flags (explicit, added,
/// prepended, appended, deleted, ordered: the reader's order) as a `u64` count and the items.
/// Items of size 0 in `LIST_OPS` vary: payloads are two `u32` indices (and a layer offset,
/// 16 bytes, from version 0.8.0); references are two indices, a layer offset and a
/// dictionary, walked as the reader walks it (`walk_dictionary`) to find the next list. The
/// reader reserves a vector for a list's count before it reads the items (a fuzzed second
/// list of references stated 2.8 × 10¹⁴, an abort).
fn check_list_op(
    w: &Walk,
    version: (u8, u8, u8),
    ty: u64,
    payload: u64,
    elem: u64,
    in_samples: bool,
    depth: u32,
) -> Result<()> {
    const REFERENCE_LIST_OP: u64 = 35;
    // The least bytes an item takes: a reference's fixed part and an empty dictionary's count.
    let elem = match (elem, ty) {
        (0, REFERENCE_LIST_OP) => 32,
        (0, _) if version >= (0, 8, 0) => 24,
        (0, _) => 8,
        (e, _) => e,
    };
    let mut pos = usize::try_from(payload).unwrap_or(usize::MAX);
    let Some(&header) = w.bytes.get(pos) else {
        return Ok(());
    };
    pos += 1;
    for bit in [1, 2, 5, 6, 3, 4] {
        if header & (1 << bit) == 0 {
            continue;
        }
        let Some((count, left)) = count_at(w.bytes, pos, 8) else {
            return Ok(());
        };
        pos += 8;
        if count.saturating_mul(elem) > left {
            return Err(w.corrupt(format!(
                "has a list op (at byte {payload}) of {count} items with {left} bytes left"
            )));
        }
        if ty != REFERENCE_LIST_OP {
            pos += (count * elem) as usize;
            continue;
        }
        for _ in 0..count {
            match walk_dictionary(w, version, pos + 24, in_samples, depth)? {
                Some(end) => pos = end,
                None => return Ok(()), // unreadable: the reader fails on the same read
            }
        }
    }
    Ok(())
}

/// The value reps of the FIELDS section: a compressed block (a chunk-count byte, 0 for one
/// LZ4 block) of `count` little-endian `u64`s.
fn value_reps(block: &[u8], count: u64) -> std::result::Result<Vec<u64>, Unreadable> {
    let (&chunks, data) = block.split_first().ok_or(Unreadable)?;
    if chunks != 0 {
        return Err(Unreadable); // the reader does not read chunked blocks
    }
    let mut out = vec![0u8; usize::try_from(count.saturating_mul(8)).map_err(|_| Unreadable)?];
    let n = lz4_flex::block::decompress_into(data, &mut out).map_err(|_| Unreadable)?;
    Ok(out[..n]
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("eight bytes")))
        .collect())
}

/// One value (read when an attribute is asked for, not at open): a count-prefixed value or a
/// list op (`COUNTED`, `LIST_OPS`), or an array: its element count, at the rep's offset,
/// against what the file holds from there: a byte or more per element stored plainly, two
/// bits or more per element in a compressed block (ints from version 0.5.0, floats from
/// 0.6.0, as the reader decides).
///
/// The reader picks how to read a value by its type first: time samples, dictionaries,
/// counted values and list ops are read at the payload whatever the array flag says (a fuzzed
/// int list op flagged as an array, its count read as an array's, aborted), and a payload of
/// 0 is an empty array but, for any other value, the file's first byte.
///
/// `in_samples`: the value is a time sample's (or the times'), where time samples again are
/// refused: USD has none, and the reader would recurse on them. `depth`: how many values
/// hold this one (`MAX_VALUE_DEPTH`).
fn check_value(
    w: &Walk,
    version: (u8, u8, u8),
    rep: u64,
    in_samples: bool,
    depth: u32,
) -> Result<()> {
    const ARRAY: u64 = 1 << 63;
    const INLINED: u64 = 1 << 62;
    const COMPRESSED: u64 = 1 << 61;
    let payload = rep & ((1 << 48) - 1);
    let ty = (rep >> 48) & 0xFF;
    if depth > MAX_VALUE_DEPTH {
        return Err(w.corrupt(format!(
            "nests values (dictionaries) more than {MAX_VALUE_DEPTH} deep, or in a loop"
        )));
    }
    // A list op is read at its payload even when flagged inlined: openusd 0.6 refuses an
    // inlined rep for the other list ops but not for a payload list op (a fuzzed inlined one
    // stated 1.9 × 10¹⁶ payloads, an abort). No valid file inlines a list op.
    if let Some(&(_, elem)) = LIST_OPS.iter().find(|(t, _)| *t == ty) {
        return check_list_op(w, version, ty, payload, elem, in_samples, depth);
    }
    // An inlined array is still read at its payload as an offset (the reader only
    // debug-asserts that arrays are not inlined): only inlined scalars carry no offset.
    if rep & INLINED != 0 && rep & ARRAY == 0 {
        return Ok(());
    }
    if ty == TIME_SAMPLES {
        return check_time_samples(w, version, payload, in_samples, depth);
    }
    if ty == DICTIONARY {
        return check_dictionary(w, version, payload, in_samples, depth);
    }
    if COUNTED.contains(&ty) {
        // A `u64` count at the offset, then four bytes or more per element.
        let pos = usize::try_from(payload).unwrap_or(usize::MAX);
        let Some((count, left)) = count_at(w.bytes, pos, 8) else {
            return Ok(());
        };
        if count > left {
            return Err(w.corrupt(format!(
                "has a value (at byte {payload}) of {count} entries with {left} bytes left"
            )));
        }
        return Ok(());
    }
    // Of the rest, arrays and the double vector are read as arrays.
    if rep & ARRAY == 0 && ty != DOUBLE_VECTOR {
        return Ok(());
    }
    if payload == 0 {
        return Ok(()); // the reader's empty array
    }
    let mut pos = usize::try_from(payload).unwrap_or(usize::MAX);
    if version < (0, 5, 0) {
        pos = pos.saturating_add(4); // the shape's size
    }
    let width = if version < (0, 7, 0) { 4 } else { 8 };
    let Some((count, left)) = count_at(w.bytes, pos, width) else {
        return Ok(()); // unreadable: the reader fails on the same read
    };
    let compressed = rep & COMPRESSED != 0
        && count >= 4
        && (((3..=6).contains(&ty) && version >= (0, 5, 0))
            || ((7..=9).contains(&ty) && version >= (0, 6, 0)));
    let limit = if compressed {
        left.saturating_mul(4 * LZ4_MAX_RATIO)
            .saturating_add(LZ4_SLACK)
    } else {
        left
    };
    if count > limit {
        return Err(w.corrupt(format!(
            "has an array value (at byte {payload}) of {count} elements with {left} bytes left"
        )));
    }
    if compressed {
        check_compressed_array(w, ty, payload, pos + width)?;
    }
    Ok(())
}

/// The compressed block of an array whose count ends at `pos`: ints store it there, floats
/// after a code byte (`i`: the block; `t`: a `u32` lookup-table size, the table, then the
/// block). The reader allocates the block's stated size before it reads it (a fuzzed int
/// array's block stated 1.8 × 10¹⁶ bytes, an abort).
fn check_compressed_array(w: &Walk, ty: u64, payload: u64, pos: usize) -> Result<()> {
    let block_at = if (3..=6).contains(&ty) {
        Some(pos)
    } else {
        match w.bytes.get(pos) {
            Some(b'i') => pos.checked_add(1),
            Some(b't') => {
                let Some((lut, left)) = count_at(w.bytes, pos + 1, 4) else {
                    return Ok(());
                };
                let elem = match ty {
                    7 => 2,
                    8 => 4,
                    _ => 8,
                };
                if lut * elem > left {
                    return Err(w.corrupt(format!(
                        "has a compressed array (at byte {payload}) with a lookup table of {lut} \
                         entries and {left} bytes left"
                    )));
                }
                (pos + 5).checked_add((lut * elem) as usize)
            }
            _ => None, // the reader refuses any other code
        }
    };
    let Some((size, left)) = block_at.and_then(|at| count_at(w.bytes, at, 8)) else {
        return Ok(());
    };
    if size > left {
        return Err(w.corrupt(format!(
            "has a compressed array (at byte {payload}) whose block states {size} bytes with \
             {left} left"
        )));
    }
    Ok(())
}

/// Time samples at `payload`, as the reader reads them: a jump (an `i64` relative to where it
/// is stored) to the times' value rep (an array of doubles), then, after that rep, a second
/// jump to the sample count (`u64`) and one value rep per sample. The times and every sample
/// are checked as values of their own (an attribute without a default is read at its first
/// sample), and the count against the bytes after it.
fn check_time_samples(
    w: &Walk,
    version: (u8, u8, u8),
    payload: u64,
    nested: bool,
    depth: u32,
) -> Result<()> {
    if nested {
        return Err(w.corrupt(format!(
            "has time samples (at byte {payload}) inside time samples"
        )));
    }
    let jump = |pos: usize| -> Option<usize> {
        let (offset, _) = count_at(w.bytes, pos, 8)?;
        pos.checked_add_signed(offset as i64 as isize)
    };
    let Some(times_at) = usize::try_from(payload).ok().and_then(jump) else {
        return Ok(()); // unreadable: the reader fails on the same read
    };
    let Some((times, _)) = count_at(w.bytes, times_at, 8) else {
        return Ok(());
    };
    check_value(w, version, times, true, depth + 1)?;
    let Some(count_at_pos) = times_at.checked_add(8).and_then(jump) else {
        return Ok(());
    };
    let Some((count, left)) = count_at(w.bytes, count_at_pos, 8) else {
        return Ok(());
    };
    if count.saturating_mul(8) > left {
        return Err(w.corrupt(format!(
            "has time samples (at byte {payload}) of {count} samples with {left} bytes left"
        )));
    }
    for k in 0..count as usize {
        let (rep, _) = count_at(w.bytes, count_at_pos + 8 + 8 * k, 8).expect("within `left`");
        check_value(w, version, rep, true, depth + 1)?;
    }
    Ok(())
}

/// A dictionary at `payload`, as the reader reads it: a `u64` count, then per entry a key (a
/// `u32` string index), an `i64` jump relative to where it is stored, and at the jump's
/// target the entry's value rep, read as a value of its own; the next entry follows that rep.
/// Jumps may lead back, so the entries a dictionary reads (with those of the dictionaries in
/// it) are bounded by the file's bytes: a real entry takes twenty.
fn check_dictionary(
    w: &Walk,
    version: (u8, u8, u8),
    payload: u64,
    in_samples: bool,
    depth: u32,
) -> Result<()> {
    let pos = usize::try_from(payload).unwrap_or(usize::MAX);
    walk_dictionary(w, version, pos, in_samples, depth).map(|_| ())
}

/// `check_dictionary` for a dictionary whose count is at `pos`: where the reader's position
/// ends up after it (`None` where the reader would fail on a read).
fn walk_dictionary(
    w: &Walk,
    version: (u8, u8, u8),
    mut pos: usize,
    in_samples: bool,
    depth: u32,
) -> Result<Option<usize>> {
    let Some((count, left)) = count_at(w.bytes, pos, 8) else {
        return Ok(None);
    };
    if count > left {
        return Err(w.corrupt(format!(
            "has a dictionary (at byte {pos}) of {count} entries with {left} bytes left"
        )));
    }
    pos += 8;
    for _ in 0..count {
        if w.entries.get() >= w.bytes.len() as u64 {
            return Err(w.corrupt(format!(
                "has dictionaries (from byte {pos}) that read more entries than the file \
                 holds bytes: their jumps loop"
            )));
        }
        w.entries.set(w.entries.get() + 1);
        let Some(jump_at) = pos.checked_add(4) else {
            return Ok(None);
        };
        let Some((offset, _)) = count_at(w.bytes, jump_at, 8) else {
            return Ok(None);
        };
        let Some(rep_at) = jump_at.checked_add_signed(offset as i64 as isize) else {
            return Ok(None);
        };
        let Some((rep, _)) = count_at(w.bytes, rep_at, 8) else {
            return Ok(None);
        };
        if (rep >> 48) & 0xFF == 0 {
            return Ok(None); // the reader refuses an invalid type
        }
        check_value(w, version, rep, in_samples, depth + 1)?;
        pos = rep_at + 8;
    }
    Ok(Some(pos))
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
        entries: std::cell::Cell::new(0),
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
                let block = w.pos + 8;
                readable!(w.compressed(count.saturating_mul(8))?);
                let reps = readable!(value_reps(&bytes[block..w.pos], count));
                for rep in reps {
                    check_value(&w, version, rep, false, 0)?;
                }
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
