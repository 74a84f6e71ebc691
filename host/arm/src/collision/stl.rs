//! STL meshes, binary or ASCII, read for their vertices only: collision fits a capsule to the
//! points a link's mesh has, so normals, facet order and shared vertices do not matter.
//!
//! Binary STL: an 80-byte header, a little-endian `u32` facet count, then 50 bytes per facet (a
//! normal and three vertices as `f32` triples, and a 2-byte attribute count). ASCII STL:
//! `solid NAME`, then `facet normal ... outer loop vertex x y z (x3) endloop endfacet`, `endsolid`.
//! A binary file may begin with the word `solid` too (many exporters write it into the header),
//! so a file whose length is exactly that of its facet count is read as binary first.

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use kinematics::nalgebra::Vector3;

/// The vertices of the STL file `path` (three per facet, repeated where facets share them), in
/// the file's units. Fails naming the file when it cannot be read, is neither form of STL, or
/// holds a number that is not finite.
pub fn read(path: &Path) -> Result<Vec<Vector3<f64>>> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read mesh {}", path.display()))?;
    parse(&bytes).with_context(|| format!("mesh {}", path.display()))
}

/// The vertices of an STL file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Vec<Vector3<f64>>> {
    let vertices = match binary_facets(bytes) {
        Some(facets) => binary(bytes, facets),
        None if bytes.trim_ascii_start().starts_with(b"solid") => ascii(bytes)?,
        None => bail!(
            "not an STL file: {} bytes, neither 84 + 50 per facet (binary) nor text starting with `solid` (ASCII)",
            bytes.len()
        ),
    };
    if vertices.is_empty() {
        bail!("the STL file has no facets");
    }
    if let Some(i) = vertices.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
        bail!("vertex {} of the STL file is not finite numbers", i + 1);
    }
    Ok(vertices)
}

/// The facet count of a binary STL whose length matches it, else `None`.
fn binary_facets(bytes: &[u8]) -> Option<usize> {
    let count: [u8; 4] = bytes.get(80..84)?.try_into().ok()?;
    let facets = u32::from_le_bytes(count) as usize;
    (facets.checked_mul(50)?.checked_add(84)? == bytes.len()).then_some(facets)
}

fn binary(bytes: &[u8], facets: usize) -> Vec<Vector3<f64>> {
    let f32_at = |at: usize| {
        let word: [u8; 4] = bytes.get(at..at + 4).and_then(|w| w.try_into().ok()).unwrap_or([0xff; 4]);
        f64::from(f32::from_le_bytes(word))
    };
    let mut vertices = Vec::with_capacity(facets * 3);
    for facet in 0..facets {
        // Skip the normal (12 bytes); the attribute count after the vertices is ignored.
        let start = 84 + facet * 50 + 12;
        for k in 0..3 {
            let at = start + k * 12;
            vertices.push(Vector3::new(f32_at(at), f32_at(at + 4), f32_at(at + 8)));
        }
    }
    vertices
}

fn ascii(bytes: &[u8]) -> Result<Vec<Vector3<f64>>> {
    let text = std::str::from_utf8(bytes).map_err(|_| anyhow!("an ASCII STL file that is not text (UTF-8)"))?;
    let mut vertices = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("vertex") {
            continue;
        }
        let numbers: Vec<&str> = words.collect();
        let parsed: Option<Vec<f64>> = numbers.iter().map(|w| w.parse::<f64>().ok()).collect();
        match parsed.as_deref() {
            Some([x, y, z]) => vertices.push(Vector3::new(*x, *y, *z)),
            _ => bail!("line {}: `vertex` needs three numbers, found {:?}", n + 1, numbers.join(" ")),
        }
    }
    if vertices.len() % 3 != 0 {
        bail!("{} vertices: an ASCII STL file has three per facet", vertices.len());
    }
    Ok(vertices)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A binary STL of `triangles`, with `solid` in its header as many exporters write it.
    pub(crate) fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut bytes = b"solid written by a test".to_vec();
        bytes.resize(80, b' ');
        bytes.extend((triangles.len() as u32).to_le_bytes());
        for t in triangles {
            bytes.extend([0u8; 12]);
            for v in t {
                for x in v {
                    bytes.extend(x.to_le_bytes());
                }
            }
            bytes.extend([0u8; 2]);
        }
        bytes
    }

    const TETRAHEDRON: [[[f32; 3]; 3]; 4] = [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
        [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.5]],
    ];

    #[test]
    fn binary_and_ascii_give_the_same_vertices() {
        let from_binary = parse(&binary_stl(&TETRAHEDRON)).unwrap();
        let mut text = String::from("solid t\n");
        for t in &TETRAHEDRON {
            text.push_str("  facet normal 0 0 0\n    outer loop\n");
            for v in t {
                text.push_str(&format!("      vertex {:e} {} {}\n", v[0], v[1], v[2]));
            }
            text.push_str("    endloop\n  endfacet\n");
        }
        text.push_str("endsolid t\n");
        let from_ascii = parse(text.as_bytes()).unwrap();
        assert_eq!(from_binary.len(), 12);
        assert_eq!(from_binary, from_ascii);
        assert_eq!(from_binary[11], Vector3::new(0.0, 1.0, 0.5));
    }

    #[test]
    fn what_is_not_an_stl_says_so() {
        let message = |bytes: &[u8]| format!("{:#}", parse(bytes).unwrap_err());
        assert!(message(b"<mesh/>").contains("not an STL file: 7 bytes"));
        assert!(
            message(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 1 2\n").contains("line 4: `vertex` needs three")
        );
        assert!(message(b"solid x\nendsolid x\n").contains("no facets"));
        let mut truncated = binary_stl(&TETRAHEDRON);
        truncated.pop();
        // One byte short of its facet count, and binary after the header: neither form.
        assert!(message(&truncated).contains("not an STL") || message(&truncated).contains("not text"));
        let nan = binary_stl(&[[[f32::NAN, 0.0, 0.0], [0.0; 3], [0.0; 3]]]);
        assert!(message(&nan).contains("vertex 1 of the STL file is not finite"));
        let missing = read(Path::new("/nonexistent/part.stl")).unwrap_err();
        assert!(format!("{missing:#}").starts_with("cannot read mesh /nonexistent/part.stl"), "{missing:#}");
    }
}
