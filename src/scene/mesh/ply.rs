//! PLY meshes (ASCII, binary little and big endian) read with the `ply-rs-bw` crate: the
//! `vertex` element's positions (`x y z`), and where every vertex has them its normals
//! (`nx ny nz`) and texture coordinates (`u v`, or `s t`, `texture_u texture_v`); the `face`
//! element's index lists (`vertex_indices` or `vertex_index`), polygons of any size. Other
//! elements and properties are read past and ignored.
use crate::geometry::{Vec2, Vec3A};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{BeginList, ElementDef, Encoding, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType};

/// A mesh as the file lists it.
#[derive(Debug, Default)]
pub struct PlyMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3A>,
    /// One per vertex where the file gives them to every vertex.
    pub normals: Option<Vec<Vec3A>>,
    /// Texture coordinates, where the file gives them to every vertex.
    pub uvs: Option<Vec<Vec2>>,
    /// Vertex indices of each face (unchecked: the caller checks them against `positions`).
    pub faces: Vec<Vec<i64>>,
}

/// Which of a vertex's optional attributes the file set.
const HAS_NORMAL: u8 = 1;
const HAS_UV: u8 = 2;

#[derive(Clone, Copy, Default)]
struct Vertex {
    p: [f32; 3],
    n: [f32; 3],
    uv: [f32; 2],
    /// `HAS_*` bits, and which position coordinates were set (bits 4–6).
    set: u8,
}

impl Vertex {
    fn store(&mut self, name: &str, value: f32) -> PropertyAccessResult {
        let (slot, bit): (&mut f32, u8) = match name {
            "x" => (&mut self.p[0], 1 << 4),
            "y" => (&mut self.p[1], 1 << 5),
            "z" => (&mut self.p[2], 1 << 6),
            "nx" => (&mut self.n[0], HAS_NORMAL),
            "ny" => (&mut self.n[1], HAS_NORMAL),
            "nz" => (&mut self.n[2], HAS_NORMAL),
            "u" | "s" | "texture_u" | "texture_s" => (&mut self.uv[0], HAS_UV),
            "v" | "t" | "texture_v" | "texture_t" => (&mut self.uv[1], HAS_UV),
            _ => return PropertyAccessResult::Ignored,
        };
        *slot = value;
        self.set |= bit;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_float(&mut self, name: &str, value: f32) -> PropertyAccessResult {
        self.store(name, value)
    }
    fn set_double(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        self.store(name, value as f32)
    }
    // Integer coordinates are rare but legal; colours and the like are ignored.
    fn set_int(&mut self, name: &str, value: i32) -> PropertyAccessResult {
        self.store(name, value as f32)
    }
    fn set_uint(&mut self, name: &str, value: u32) -> PropertyAccessResult {
        self.store(name, value as f32)
    }
    fn set_short(&mut self, name: &str, value: i16) -> PropertyAccessResult {
        self.store(name, f32::from(value))
    }
    fn set_ushort(&mut self, name: &str, value: u16) -> PropertyAccessResult {
        self.store(name, f32::from(value))
    }
    fn set_char(&mut self, name: &str, value: i8) -> PropertyAccessResult {
        self.store(name, f32::from(value))
    }
    fn set_uchar(&mut self, name: &str, value: u8) -> PropertyAccessResult {
        self.store(name, f32::from(value))
    }
}

/// A face: its index list in whichever integer type the file uses.
#[derive(Default)]
struct Face {
    signed: Vec<i32>,
    unsigned: Vec<u32>,
    other: Vec<i64>,
}

fn is_index_list(name: &str) -> bool {
    matches!(name, "vertex_indices" | "vertex_index")
}

impl Face {
    fn indices(self) -> Vec<i64> {
        if !self.signed.is_empty() {
            self.signed.into_iter().map(i64::from).collect()
        } else if !self.unsigned.is_empty() {
            self.unsigned.into_iter().map(i64::from).collect()
        } else {
            self.other
        }
    }
    fn set_other(&mut self, name: &str, values: impl Iterator<Item = i64>) -> PropertyAccessResult {
        if !is_index_list(name) {
            return PropertyAccessResult::Ignored;
        }
        self.other = values.collect();
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Self::default()
    }
    fn begin_list_int(&mut self, name: &str, _len: usize) -> BeginList<'_, i32> {
        if is_index_list(name) { BeginList::Fill(&mut self.signed) } else { BeginList::UseSetter }
    }
    fn begin_list_uint(&mut self, name: &str, _len: usize) -> BeginList<'_, u32> {
        if is_index_list(name) { BeginList::Fill(&mut self.unsigned) } else { BeginList::UseSetter }
    }
    fn set_list_int(&mut self, _: &str, _: Vec<i32>) -> PropertyAccessResult {
        PropertyAccessResult::Ignored
    }
    fn set_list_uint(&mut self, _: &str, _: Vec<u32>) -> PropertyAccessResult {
        PropertyAccessResult::Ignored
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set_other(name, v.into_iter().map(i64::from))
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set_other(name, v.into_iter().map(i64::from))
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set_other(name, v.into_iter().map(i64::from))
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set_other(name, v.into_iter().map(i64::from))
    }
    fn set_list_float(&mut self, _: &str, _: Vec<f32>) -> PropertyAccessResult {
        PropertyAccessResult::Ignored
    }
    fn set_list_double(&mut self, _: &str, _: Vec<f64>) -> PropertyAccessResult {
        PropertyAccessResult::Ignored
    }
}

/// An element the renderer does not use: read past.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// Bytes of a binary scalar.
fn scalar_bytes(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes one entry of `element` takes in the payload: its scalars and list
/// lengths in binary, a byte per property (at least one) in ASCII.
fn min_entry_bytes(element: &ElementDef, binary: bool) -> usize {
    if !binary {
        return element.properties.len().max(1);
    }
    let bytes = element
        .properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_bytes(t),
        })
        .sum::<usize>();
    bytes.max(1)
}

/// Parses the bytes of a PLY file. Errors name the line where the parser knows it.
///
/// The PLY parser's message as one plain line: its first line (without the parser's own
/// `Line N:`, which the caller gives) and the text it could not read, not the parser's nested
/// debug dumps (`ParseError { location: LineCol { … } }`).
fn plain_message(text: &str) -> String {
    let mut lines = text.lines();
    let first = lines.next().unwrap_or("").trim();
    let first = match first.strip_prefix("Line ").and_then(|rest| rest.split_once(": ")) {
        Some((n, rest)) if n.chars().all(|c| c.is_ascii_digit()) => rest,
        _ => first,
    };
    let first = first.trim_end_matches('.');
    let quoted = lines.find_map(|l| l.trim().strip_prefix("String: ")).map(|q| q.trim().trim_matches('\'').trim_end());
    match quoted {
        Some(q) if !q.is_empty() => format!("{first}: `{q}`"),
        _ => first.to_string(),
    }
}

/// An element may declare no more entries than the file's bytes can hold: the parser would
/// otherwise build every declared entry of an element without properties (found by fuzzing:
/// 125 bytes declaring 68 M vertices took 2.4 GB).
pub fn parse(bytes: &[u8]) -> Result<PlyMesh, String> {
    let mut reader = Reader::new(std::io::Cursor::new(bytes));
    let describe = |e: ply_rs_bw::parser::ParseError| {
        let text = plain_message(&e.to_string());
        match e.line() {
            Some(line) => format!("line {line}: {text}"),
            None => text,
        }
    };
    let header = Parser::<Vertex>::new().read_header(&mut reader).map_err(describe)?;
    let binary = !matches!(header.encoding, Encoding::Ascii);
    for element in header.elements.values() {
        let room = bytes.len() / min_entry_bytes(element, binary);
        if element.count > room {
            return Err(format!(
                "element `{}` declares {} entries, more than the file's {} bytes can hold",
                element.name,
                element.count,
                bytes.len()
            ));
        }
    }
    let mut mesh = PlyMesh::default();
    let (mut has_vertices, mut has_faces) = (false, false);
    for element in header.elements.values() {
        match element.name.as_str() {
            "vertex" if !has_vertices => {
                has_vertices = true;
                let vertices = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(describe)?;
                let xyz = 0b111 << 4;
                if let Some(i) = vertices.iter().position(|v| v.set & xyz != xyz) {
                    return Err(format!("vertex {} lacks one of x, y, z", i + 1));
                }
                let all = |bit: u8| !vertices.is_empty() && vertices.iter().all(|v| v.set & bit != 0);
                mesh.normals = all(HAS_NORMAL).then(|| vertices.iter().map(|v| Vec3A::from_array(v.n)).collect());
                mesh.uvs = all(HAS_UV).then(|| vertices.iter().map(|v| Vec2::from_array(v.uv)).collect());
                mesh.positions = vertices.iter().map(|v| Vec3A::from_array(v.p)).collect();
            }
            "face" if !has_faces => {
                has_faces = true;
                let faces =
                    Parser::<Face>::new().read_payload_for_element(&mut reader, element, &header).map_err(describe)?;
                mesh.faces = faces.into_iter().map(Face::indices).collect();
            }
            _ => {
                Parser::<Skip>::new().read_payload_for_element(&mut reader, element, &header).map_err(describe)?;
            }
        }
    }
    if !has_vertices || !has_faces {
        return Err("a PLY mesh needs a `vertex` and a `face` element".into());
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment a unit square\nelement vertex 4\n\
        property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n\
        property float nz\nproperty float u\nproperty float v\nproperty uchar red\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 0 0 1 0 0 255\n1 0 0 0 0 1 1 0 255\n1 1 0 0 0 1 1 1 255\n0 1 0 0 0 1 0 1 255\n4 0 1 2 3\n";

    /// A malformed PLY is described in one plain line: where, what, and the text it could not
    /// read; not the parser's debug dumps.
    #[test]
    fn errors_are_one_plain_line() {
        let bad_value = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nend_header\n1 0 oops\n";
        let bad_type = "ply\nformat ascii 1.0\nelement vertex 1\nproperty floaty x\nend_header\n";
        for (text, want) in [(bad_value, "line 8: "), (bad_type, "line 4: ")] {
            let e = parse(text.as_bytes()).unwrap_err();
            assert!(e.starts_with(want) && !e.contains('\n') && !e.contains('\t') && !e.contains(" { "), "{e}");
        }
        assert!(parse(bad_value.as_bytes()).unwrap_err().contains("`1 0 oops`"));
    }

    #[test]
    fn ascii_with_normals_and_texture_coordinates() {
        let m = parse(ASCII.as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], Vec3A::new(1.0, 1.0, 0.0));
        assert_eq!(m.normals.as_ref().unwrap()[1], Vec3A::Z);
        assert_eq!(m.uvs.as_ref().unwrap()[3], Vec2::new(0.0, 1.0));
        assert_eq!(m.faces, vec![vec![0, 1, 2, 3]]);
    }

    /// The same square in binary little- and big-endian form, with double coordinates and an
    /// unsigned index list, no normals, and an extra element in between.
    #[test]
    fn binary_in_both_byte_orders() {
        for (format, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
            let mut bytes = format!(
                "ply\nformat {format} 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
                 property double z\nelement edge 1\nproperty int a\nelement face 1\n\
                 property list uchar uint vertex_index\nend_header\n"
            )
            .into_bytes();
            let f64s = |v: f64| if big { v.to_be_bytes() } else { v.to_le_bytes() };
            let u32s = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
            for p in [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.5]] {
                p.iter().for_each(|&c| bytes.extend(f64s(c)));
            }
            bytes.extend(u32s(7));
            bytes.push(3);
            [0, 1, 2].iter().for_each(|&i| bytes.extend(u32s(i)));
            let m = parse(&bytes).unwrap();
            assert_eq!(m.positions[2], Vec3A::new(0.0, 3.0, 0.5), "{format}");
            assert!(m.normals.is_none() && m.uvs.is_none());
            assert_eq!(m.faces, vec![vec![0, 1, 2]]);
        }
    }

    #[test]
    fn malformed_files_are_errors() {
        let cases: [&[u8]; 8] = [
            b"",
            b"not a ply file\n",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n\x00\x00",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0\n",
            // The fuzzer's out-of-memory input: 68 M vertices without properties.
            include_bytes!("../../../fuzz/artifacts/ply/oom-9a6827968804c1f93ff78e1f1cab3c10c1af3b9c"),
            b"ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n",
        ];
        for (k, bytes) in cases.iter().enumerate() {
            assert!(parse(bytes).is_err(), "case {k} parsed");
        }
    }
}
