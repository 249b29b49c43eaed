//! The `.prisms` file: a versioned, checksummed little-endian binary of a `PrismTable`.
//! The layout is documented in `docs/prism-format.md`; keep the two in step.
//!
//! The reader never trusts a count: the file length implied by the header is computed with
//! checked arithmetic and compared to the real length before anything is allocated, and
//! every index and float is checked after the checksum.

use crate::bake::{Prism, PrismTable, TableSource};
use crate::error::{Error, Result};
use crate::heightmap::{DisplaceParams, Wrap};
use crate::mesh::{SeamEdge, UpAxis};
use glam::{Vec2, Vec3};
use std::io::Write;
use std::path::Path;

pub const MAGIC: [u8; 8] = *b"PRISMBK\0";
pub const VERSION: u32 = 3;
/// The oldest version this build reads: version 2 lacks the source section (a render of it
/// goes without the mesh's cameras, materials and lights, and stands Y up).
pub const OLDEST_VERSION: u32 = 2;
/// Header flag: the asset's up axis is +Z (USD `upAxis = "Z"`); else +Y.
pub const FLAG_Z_UP: u32 = 1;
/// Bytes per vertex record: position, normal (3 f32 each), uv (2 f32).
pub const VERTEX_BYTES: usize = 32;
/// Bytes per prism record: 3 u32 indices, d_min, d_max, lambda_lo, lambda_hi, texel_world, flags.
pub const PRISM_BYTES: usize = 36;
/// Bytes per seam record: 2 u32 prism indices, 2 u8 edge slots, 2 reserved bytes.
pub const SEAM_BYTES: usize = 12;
const FIXED_HEADER: usize = 8 + 4 + 3 * 8 + 4 * 6 + 32 + 4;
/// The source section after the map path (version 3): mesh path length, UV set, mesh hash;
/// the mesh path's own bytes are counted apart.
const SOURCE_FIXED: usize = 4 + 4 + 32;
const CHECKSUM_BYTES: usize = 32;
const MAX_PATH: usize = 4096;
/// Refuse tables beyond this many prisms (far above any base mesh PDM is meant for).
pub const MAX_PRISMS: u64 = 1 << 28;

pub fn encode(table: &PrismTable) -> Vec<u8> {
    let path = table.map_path.as_bytes();
    let source = &table.source;
    let mut out = Vec::with_capacity(encoded_len(table));
    out.extend_from_slice(&MAGIC);
    put_u32(&mut out, VERSION);
    put_u64(&mut out, table.positions.len() as u64);
    put_u64(&mut out, table.prisms.len() as u64);
    put_u64(&mut out, table.seams.len() as u64);
    put_u32(&mut out, table.map_width);
    put_u32(&mut out, table.map_height);
    put_u32(
        &mut out,
        match table.wrap {
            Wrap::Repeat => 0,
            Wrap::Clamp => 1,
        },
    );
    put_f32(&mut out, table.params.scale);
    put_f32(&mut out, table.params.midlevel);
    put_u32(
        &mut out,
        match source.up_axis {
            UpAxis::Y => 0,
            UpAxis::Z => FLAG_Z_UP,
        },
    );
    out.extend_from_slice(&table.input_hash);
    put_u32(&mut out, path.len() as u32);
    out.extend_from_slice(path);
    put_u32(&mut out, source.mesh_path.len() as u32);
    out.extend_from_slice(source.mesh_path.as_bytes());
    put_u32(&mut out, source.uv_set);
    out.extend_from_slice(&source.mesh_hash);
    for p in &table.positions {
        put_vec3(&mut out, *p);
    }
    for n in &table.normals {
        put_vec3(&mut out, *n);
    }
    for uv in &table.uvs {
        put_f32(&mut out, uv.x);
        put_f32(&mut out, uv.y);
    }
    for p in &table.prisms {
        for i in p.tri {
            put_u32(&mut out, i);
        }
        for f in [p.d_min, p.d_max, p.lambda_lo, p.lambda_hi, p.texel_world] {
            put_f32(&mut out, f);
        }
        put_u32(&mut out, p.flags);
    }
    for seam in &table.seams {
        put_u32(&mut out, seam.faces[0]);
        put_u32(&mut out, seam.faces[1]);
        out.extend_from_slice(&[seam.edges[0], seam.edges[1], 0, 0]);
    }
    let sum = blake3::hash(&out);
    out.extend_from_slice(sum.as_bytes());
    out
}

/// The bytes `encode(table)` writes.
pub fn encoded_len(table: &PrismTable) -> usize {
    layout_len(
        table.positions.len(),
        table.prisms.len(),
        table.seams.len(),
        table.map_path.len() + table.source.mesh_path.len(),
    )
}

/// The bytes of a table with these counts, and `paths` bytes of map and mesh path.
pub fn layout_len(vertices: usize, prisms: usize, seams: usize, paths: usize) -> usize {
    FIXED_HEADER
        + SOURCE_FIXED
        + paths
        + vertices * VERTEX_BYTES
        + prisms * PRISM_BYTES
        + seams * SEAM_BYTES
        + CHECKSUM_BYTES
}

/// Write atomically: a temp file in the same folder, then rename.
pub fn write(path: &Path, table: &PrismTable) -> Result<()> {
    write_atomic(path, &encode(table))
}

pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

pub fn read(path: &Path) -> Result<PrismTable> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode(&bytes).map_err(|what| Error::invalid(path, what))
}

/// Read only the input hash, for the skip-work check (None if the file is not a valid table).
pub fn read_input_hash(path: &Path) -> Option<[u8; 32]> {
    let table = read(path).ok()?;
    Some(table.input_hash)
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> std::result::Result<&[u8], String> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                format!(
                    "truncated prism table: needs {} more bytes at offset {} (re-bake the table)",
                    n, self.pos
                )
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> std::result::Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> std::result::Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn vec3(&mut self) -> std::result::Result<Vec3, String> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
}

/// Decode a table; the error says what is wrong and what to do.
pub fn decode(bytes: &[u8]) -> std::result::Result<PrismTable, String> {
    let mut r = Reader { bytes, pos: 0 };
    let magic = r
        .take(8)
        .map_err(|_| "not a prism table: file is shorter than its 8-byte magic".to_string())?;
    if magic != MAGIC {
        return Err(
            "not a prism table (bad magic; expected a file written by `prismbake bake`)".into(),
        );
    }
    let version = r.u32()?;
    if !(OLDEST_VERSION..=VERSION).contains(&version) {
        return Err(format!(
            "prism table format version {version} is not supported (this prismbake reads versions {OLDEST_VERSION} to {VERSION}); re-bake the table with this version"
        ));
    }
    let nv = r.u64()?;
    let np = r.u64()?;
    let ns = r.u64()?;
    if np > MAX_PRISMS || nv > 3 * MAX_PRISMS || ns > 3 * MAX_PRISMS {
        return Err(format!("prism table claims {np} prisms, {nv} vertices and {ns} seams, more than the limit of {MAX_PRISMS} prisms: the file is corrupt"));
    }
    let map_width = r.u32()?;
    let map_height = r.u32()?;
    let wrap = match r.u32()? {
        0 => Wrap::Repeat,
        1 => Wrap::Clamp,
        w => {
            return Err(format!(
                "unknown wrap mode {w} in header (file is corrupt; re-bake)"
            ))
        }
    };
    let params = DisplaceParams {
        scale: r.f32()?,
        midlevel: r.f32()?,
    };
    let flags = r.u32()?;
    if flags & !FLAG_Z_UP != 0 {
        return Err(format!(
            "unknown header flags {flags:#x} (the file is corrupt, or newer than this prismbake: re-bake it)"
        ));
    }
    let mut input_hash = [0u8; 32];
    input_hash.copy_from_slice(r.take(32)?);
    let path_len = path_len(r.u32()?, "map")?;
    // Version 3's source section: its mesh path's length is read ahead of the size check.
    let (source_len, mesh_path_len) = match version {
        2 => (0, 0),
        _ => {
            let at = r.pos + path_len;
            let field = bytes.get(at..at + 4).ok_or(
                "truncated prism table: its header ends before the mesh path (re-bake it)",
            )?;
            let n = path_len_of(field)?;
            (SOURCE_FIXED + n, n)
        }
    };
    let expected = (FIXED_HEADER as u64)
        .checked_add((path_len + source_len) as u64)
        .and_then(|s| s.checked_add(nv.checked_mul(VERTEX_BYTES as u64)?))
        .and_then(|s| s.checked_add(np.checked_mul(PRISM_BYTES as u64)?))
        .and_then(|s| s.checked_add(ns.checked_mul(SEAM_BYTES as u64)?))
        .and_then(|s| s.checked_add(CHECKSUM_BYTES as u64))
        .ok_or("prism table counts overflow: the file is corrupt")?;
    if expected != bytes.len() as u64 {
        return Err(format!(
            "prism table is {} bytes but its header ({nv} vertices, {np} prisms, {ns} seams) implies {expected}: the file is truncated or corrupt (re-bake it)",
            bytes.len()
        ));
    }
    let body_end = bytes.len() - CHECKSUM_BYTES;
    if blake3::hash(&bytes[..body_end]).as_bytes() != &bytes[body_end..] {
        return Err("prism table checksum mismatch: the file is corrupt (re-bake it)".into());
    }
    let map_path = String::from_utf8(r.take(path_len)?.to_vec())
        .map_err(|_| "map path is not UTF-8 (file is corrupt)".to_string())?;
    let up_axis = match flags & FLAG_Z_UP {
        0 => UpAxis::Y,
        _ => UpAxis::Z,
    };
    let source = match version {
        2 => TableSource {
            up_axis,
            ..TableSource::default()
        },
        _ => {
            r.take(4)?; // the mesh path's length, read above
            let mesh_path = String::from_utf8(r.take(mesh_path_len)?.to_vec())
                .map_err(|_| "mesh path is not UTF-8 (file is corrupt)".to_string())?;
            let uv_set = r.u32()?;
            let mut mesh_hash = [0u8; 32];
            mesh_hash.copy_from_slice(r.take(32)?);
            TableSource {
                mesh_path,
                uv_set,
                mesh_hash,
                up_axis,
            }
        }
    };
    let (nv, np) = (nv as usize, np as usize);
    let positions = (0..nv)
        .map(|_| r.vec3())
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let normals = (0..nv)
        .map(|_| r.vec3())
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let uvs = (0..nv)
        .map(|_| Ok(Vec2::new(r.f32()?, r.f32()?)))
        .collect::<std::result::Result<Vec<_>, String>>()?;
    let mut prisms = Vec::with_capacity(np);
    for i in 0..np {
        let tri = [r.u32()?, r.u32()?, r.u32()?];
        let p = Prism {
            tri,
            d_min: r.f32()?,
            d_max: r.f32()?,
            lambda_lo: r.f32()?,
            lambda_hi: r.f32()?,
            texel_world: r.f32()?,
            flags: r.u32()?,
        };
        if let Some(&bad) = tri.iter().find(|&&v| v as usize >= nv) {
            return Err(format!("prism {i} references vertex {bad} but the table has {nv} vertices (corrupt; re-bake)"));
        }
        let finite = [p.d_min, p.d_max, p.lambda_lo, p.lambda_hi, p.texel_world]
            .iter()
            .all(|f| f.is_finite());
        if !finite || p.d_min > p.d_max || p.lambda_lo > p.lambda_hi {
            return Err(format!(
                "prism {i} has a non-finite or inverted extent (corrupt; re-bake)"
            ));
        }
        prisms.push(p);
    }
    let mut seams = Vec::with_capacity(ns as usize);
    for i in 0..ns as usize {
        let faces = [r.u32()?, r.u32()?];
        let e = r.take(4)?;
        let edges = [e[0], e[1]];
        if faces.iter().any(|&f| f as usize >= np)
            || edges.iter().any(|&k| k > 2)
            || faces[0] == faces[1]
            || e[2] != 0
            || e[3] != 0
        {
            return Err(format!("seam {i} names prisms {faces:?}, edges {edges:?} (reserved bytes {:?}), but the table has {np} prisms, edges 0..2 and zero reserved bytes (corrupt; re-bake)", [e[2], e[3]]));
        }
        seams.push(SeamEdge { faces, edges });
    }
    if let Some(v) = (0..nv)
        .find(|&v| !(positions[v].is_finite() && normals[v].is_finite() && uvs[v].is_finite()))
    {
        return Err(format!(
            "vertex {v} has a NaN or infinite value (corrupt; re-bake)"
        ));
    }
    Ok(PrismTable {
        positions,
        normals,
        uvs,
        prisms,
        params,
        map_width,
        map_height,
        input_hash,
        map_path,
        wrap,
        seams,
        source,
    })
}

/// A path's length field, checked against the limit.
fn path_len(n: u32, what: &str) -> std::result::Result<usize, String> {
    match n as usize {
        n if n > MAX_PATH => Err(format!(
            "{what} path length {n} exceeds {MAX_PATH} bytes: the file is corrupt"
        )),
        n => Ok(n),
    }
}

fn path_len_of(field: &[u8]) -> std::result::Result<usize, String> {
    path_len(u32::from_le_bytes(field.try_into().unwrap()), "mesh")
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_vec3(out: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        put_f32(out, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::PRISM_FLAT;

    fn small_table() -> PrismTable {
        PrismTable {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::Y],
            prisms: vec![Prism {
                tri: [0, 1, 2],
                d_min: -0.5,
                d_max: 0.25,
                lambda_lo: -0.5,
                lambda_hi: 0.25,
                texel_world: 0.01,
                flags: PRISM_FLAT,
            }],
            params: DisplaceParams {
                scale: 0.1,
                midlevel: 0.5,
            },
            map_width: 64,
            map_height: 32,
            input_hash: [7; 32],
            map_path: "maps/h.png".into(),
            wrap: Wrap::Clamp,
            seams: vec![],
            source: TableSource {
                mesh_path: "rock.usda".into(),
                uv_set: 1,
                mesh_hash: [9; 32],
                up_axis: UpAxis::Z,
            },
        }
    }

    /// `table` as version 2 wrote it: no source section, the version field 2.
    fn version_2(table: &PrismTable) -> Vec<u8> {
        let mut b = encode(table);
        b.truncate(b.len() - CHECKSUM_BYTES);
        let at = FIXED_HEADER + table.map_path.len();
        b.drain(at..at + SOURCE_FIXED + table.source.mesh_path.len());
        b[8..12].copy_from_slice(&2u32.to_le_bytes());
        let sum = blake3::hash(&b);
        b.extend_from_slice(sum.as_bytes());
        b
    }

    /// Two prisms sharing a seam edge (edge 0 of each).
    fn seamed_table() -> PrismTable {
        let mut t = small_table();
        t.positions.push(Vec3::ONE);
        t.normals.push(Vec3::Z);
        t.uvs.push(Vec2::ONE);
        t.prisms.push(Prism {
            tri: [3, 2, 1],
            ..t.prisms[0]
        });
        t.seams = vec![SeamEdge {
            faces: [0, 1],
            edges: [0, 0],
        }];
        t
    }

    #[test]
    fn round_trip() {
        let t = small_table();
        let bytes = encode(&t);
        assert_eq!(bytes.len(), layout_len(3, 1, 0, 10 + 9));
        assert_eq!(bytes.len(), encoded_len(&t));
        let back = decode(&bytes).unwrap();
        assert_eq!(back.source, t.source);
        assert_eq!(back.prisms, t.prisms);
        assert_eq!(back.positions, t.positions);
        assert_eq!(back.uvs, t.uvs);
        assert_eq!(back.map_path, t.map_path);
        assert_eq!(back.wrap, Wrap::Clamp);
        assert_eq!(back.input_hash, t.input_hash);
        let t = seamed_table();
        let bytes = encode(&t);
        assert_eq!(bytes.len(), layout_len(4, 2, 1, 10 + 9));
        assert_eq!(decode(&bytes).unwrap().seams, t.seams);
    }

    #[test]
    fn rejects_seams_naming_missing_prisms_or_edges() {
        for (faces, edges) in [([0, 2], [0, 0]), ([0, 1], [3, 0]), ([1, 1], [0, 1])] {
            let mut t = seamed_table();
            t.seams[0] = SeamEdge { faces, edges };
            let err = decode(&encode(&t)).unwrap_err();
            assert!(err.contains("seam 0"), "{err}");
        }
        // The record's reserved bytes must be zero (a table is re-encoded byte for byte).
        let mut b = encode(&seamed_table());
        let n = b.len() - 32;
        b[n - 1] = 7;
        let sum = blake3::hash(&b[..n]);
        b[n..].copy_from_slice(sum.as_bytes());
        assert!(decode(&b).unwrap_err().contains("seam 0"));
    }

    /// Frozen header bytes: a change to the layout must bump VERSION and the doc.
    #[test]
    fn frozen_header() {
        let bytes = encode(&small_table());
        assert_eq!(&bytes[..8], b"PRISMBK\0");
        assert_eq!(&bytes[8..12], &[3, 0, 0, 0]); // version
        assert_eq!(
            &bytes[12..36],
            &[3, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
        ); // counts: vertices, prisms, seams
        assert_eq!(&bytes[36..44], &[64, 0, 0, 0, 32, 0, 0, 0]); // map size
        assert_eq!(&bytes[44..48], &[1, 0, 0, 0]); // clamp
        assert_eq!(&bytes[56..60], &[1, 0, 0, 0]); // flags: Z up
                                                   // After the map path: the mesh path's length and bytes, the UV set, the mesh hash.
        let source = &bytes[96 + 10..96 + 10 + SOURCE_FIXED + 9];
        assert_eq!(&source[..13], b"\x09\0\0\0rock.usda");
        assert_eq!(&source[13..17], &[1, 0, 0, 0]);
        assert_eq!(&source[17..], &[9; 32]);
        // A seam record: two prism indices, two edge slots, two reserved bytes.
        let bytes = encode(&seamed_table());
        let n = bytes.len() - 32;
        assert_eq!(&bytes[n - 12..n], &[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn every_truncation_is_a_clean_error() {
        for bytes in [encode(&small_table()), version_2(&small_table())] {
            for n in 0..bytes.len() {
                assert!(decode(&bytes[..n]).is_err(), "prefix of {n} bytes decoded");
            }
        }
    }

    /// A version-2 table (no source section) still reads: the same geometry, no mesh named,
    /// and the up axis its flags held.
    #[test]
    fn reads_version_2_without_its_source() {
        let t = seamed_table();
        let back = decode(&version_2(&t)).unwrap();
        assert_eq!(back.prisms, t.prisms);
        assert_eq!(back.seams, t.seams);
        assert_eq!(back.map_path, t.map_path);
        assert_eq!(
            back.source,
            TableSource {
                up_axis: UpAxis::Z,
                ..TableSource::default()
            }
        );
    }

    #[test]
    fn rejects_unknown_flags_and_overlong_mesh_paths() {
        let reseal = |mut b: Vec<u8>| {
            let n = b.len() - CHECKSUM_BYTES;
            let sum = blake3::hash(&b[..n]);
            b[n..].copy_from_slice(sum.as_bytes());
            b
        };
        let mut b = encode(&small_table());
        b[56] = 2;
        assert!(decode(&reseal(b)).unwrap_err().contains("flags"));
        let mut b = encode(&small_table());
        b[106..110].copy_from_slice(&5000u32.to_le_bytes());
        assert!(decode(&reseal(b))
            .unwrap_err()
            .contains("mesh path length 5000"));
    }

    #[test]
    fn rejects_other_version_bad_checksum_and_absurd_counts() {
        let mut b = encode(&small_table());
        b[8] = 1;
        assert!(decode(&b).unwrap_err().contains("version 1"));
        b[8] = 4;
        assert!(decode(&b).unwrap_err().contains("version 4"));
        let mut b = encode(&small_table());
        let n = b.len();
        b[n - 40] ^= 1;
        assert!(decode(&b).unwrap_err().contains("checksum"));
        let mut b = encode(&small_table());
        b[20..28].copy_from_slice(&(1_000_000_000_000u64).to_le_bytes());
        assert!(decode(&b).unwrap_err().contains("limit"));
        let mut b = encode(&small_table());
        b[20..28].copy_from_slice(&(1000u64).to_le_bytes());
        assert!(decode(&b).unwrap_err().contains("implies"));
    }

    #[test]
    fn random_bytes_never_panic() {
        let good = encode(&small_table());
        let mut state = 12345u32;
        for _ in 0..20_000 {
            let mut b = good.clone();
            for _ in 0..4 {
                state = crate::rng::pcg_hash(state);
                let i = state as usize % b.len();
                b[i] = (state >> 8) as u8;
            }
            let _ = decode(&b);
        }
    }
}
