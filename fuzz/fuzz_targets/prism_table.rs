//! bytes → `prism_file::decode`: any input is a clean `Err` or a table whose every index
//! is in range (the decoder's promise; a panic or an out-of-range index is a bug).
//!
//! A random mutation almost never keeps the blake3 checksum valid, which would leave the
//! checks behind it (indices, finiteness, UTF-8 path) unfuzzed: so each input is decoded
//! twice, as given and with its last 32 bytes replaced by the checksum of the rest.
#![no_main]

use libfuzzer_sys::fuzz_target;
use prismbake::prism_file::{decode, encode};

fn check(bytes: &[u8]) {
    if let Ok(table) = decode(bytes) {
        let nv = table.positions.len();
        assert!(table.normals.len() == nv && table.uvs.len() == nv);
        assert!(table.prisms.iter().all(|p| p.tri.iter().all(|&i| (i as usize) < nv)));
        // A decoded table re-encodes to the same bytes (nothing is silently dropped); a
        // version-2 table re-encodes as version 3, which decodes to the same table.
        let mut expected = bytes.to_vec();
        with_checksum(&mut expected);
        let again = encode(&table);
        match bytes[8..12] == 2u32.to_le_bytes() {
            false => assert_eq!(again, expected),
            true => assert_eq!(encode(&decode(&again).expect("re-encoded")), again),
        }
    }
}

/// Replace the last 32 bytes with the blake3 of the rest.
fn with_checksum(bytes: &mut [u8]) {
    let body = bytes.len() - 32;
    let sum = blake3::hash(&bytes[..body]);
    bytes[body..].copy_from_slice(sum.as_bytes());
}

fuzz_target!(|data: &[u8]| {
    check(data);
    if data.len() >= 32 {
        let mut fixed = data.to_vec();
        with_checksum(&mut fixed);
        check(&fixed);
    }
});
