//! Reading PLY: the header checked against the limits before any element is read, then
//! vertices (any numeric property type) and faces into a [`PlyData`].

use super::*;

/// A vertex as parsed (every numeric type routed through `set_num`).
#[derive(Debug, Clone, Copy, Default)]
struct VertexIn {
    p: [f32; 3],
    n: [f32; 3],
    c: [u8; 3],
    s: f32,
    s_set: bool,
}

impl VertexIn {
    fn set_num(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        match name {
            "x" => self.p[0] = v as f32,
            "y" => self.p[1] = v as f32,
            "z" => self.p[2] = v as f32,
            "nx" => self.n[0] = v as f32,
            "ny" => self.n[1] = v as f32,
            "nz" => self.n[2] = v as f32,
            "red" => self.c[0] = v.clamp(0.0, 255.0) as u8,
            "green" => self.c[1] = v.clamp(0.0, 255.0) as u8,
            "blue" => self.c[2] = v.clamp(0.0, 255.0) as u8,
            "alpha" => return PropertyAccessResult::Ignored,
            // Properties arrive in header order: the first unknown one is the scalar.
            _ if !self.s_set => {
                self.s = v as f32;
                self.s_set = true;
            }
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for VertexIn {
    fn new() -> Self {
        Self::default()
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set_num(name, f64::from(v))
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set_num(name, v)
    }
}

/// A face as parsed: the first three indices, the list length, and whether any index was
/// negative.
#[derive(Debug, Clone, Copy, Default)]
struct FaceIn {
    idx: [u32; 3],
    len: usize,
    negative: bool,
}

impl FaceIn {
    fn set_list<T: Copy + TryInto<u32>>(&mut self, name: &str, v: &[T]) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.len = v.len();
        for (slot, x) in self.idx.iter_mut().zip(v) {
            match (*x).try_into() {
                Ok(u) => *slot = u,
                Err(_) => self.negative = true,
            }
        }
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for FaceIn {
    fn new() -> Self {
        Self::default()
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.set_list(name, &v)
    }
}

/// An element we do not use: every property is ignored.
#[derive(Debug, Clone, Copy, Default)]
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

fn is_int(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

fn scalar_size(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// What the vertex element declares.
struct VertexLayout {
    normals: bool,
    colors: bool,
    scalar: Option<String>,
}

/// Checks the header against what [`PlyData`] can hold, and that the declared element counts
/// fit in the file (so nothing is sized by an unchecked count).
fn check_header(
    path: &Path,
    header: &Header,
    file_len: Option<u64>,
    limits: &Limits,
) -> Result<VertexLayout> {
    let err = |m: String| IoError::Ply {
        path: path.to_path_buf(),
        message: m,
    };
    let Some(vertex) = header.elements.get("vertex") else {
        return Err(err("no `vertex` element".into()));
    };
    let mut min_payload: u64 = 0;
    let mut entries: u64 = 0;
    for (name, e) in &header.elements {
        entries = entries.saturating_add(e.count as u64);
        if entries > limits.max_ply_elements {
            return Err(IoError::too_large(
                path,
                format!(
                    "the header declares more than {} elements, over the PLY limit (raise it with --max-memory)",
                    limits.max_ply_elements
                ),
            ));
        }
        if e.properties.is_empty() && e.count > 0 {
            return Err(err(format!(
                "element `{name}` declares {} entries but no properties",
                e.count
            )));
        }
        // Smallest possible encoding of one entry: binary = scalar sizes + list counts;
        // ASCII = one digit plus a separator per property.
        let per: u64 = e
            .properties
            .values()
            .map(|p| match (&header.encoding, &p.data_type) {
                (Encoding::Ascii, _) => 2,
                (_, PropertyType::Scalar(t)) => scalar_size(t),
                (_, PropertyType::List(t, _)) => scalar_size(t),
            })
            .sum();
        min_payload = (e.count as u64)
            .checked_mul(per)
            .and_then(|b| b.checked_add(min_payload))
            .ok_or_else(|| err(format!("element `{name}` count {} overflows", e.count)))?;
    }
    if let Some(file_len) = file_len
        && min_payload > file_len
    {
        return Err(err(format!(
            "the header declares at least {min_payload} bytes of data, the file has {file_len} bytes (truncated?)"
        )));
    }
    let props = &vertex.properties;
    let scalar_of = |n: &str| match props.get(n).map(|p| &p.data_type) {
        Some(PropertyType::Scalar(t)) => Some(t.clone()),
        _ => None,
    };
    for n in ["x", "y", "z"] {
        if scalar_of(n).is_none() {
            return Err(err(format!("vertex element lacks scalar property `{n}`")));
        }
    }
    let group = |names: [&str; 3], what: &str| -> Result<bool> {
        let present = names.iter().filter(|n| props.contains_key(**n)).count();
        match present {
            0 => Ok(false),
            3 if names.iter().all(|n| scalar_of(n).is_some()) => Ok(true),
            _ => Err(err(format!(
                "vertex {what} need scalar properties {names:?}, found {present} of them"
            ))),
        }
    };
    let normals = group(["nx", "ny", "nz"], "normals")?;
    let colors = group(["red", "green", "blue"], "colours")?;
    if colors
        && !["red", "green", "blue"]
            .iter()
            .all(|n| scalar_of(n).is_some_and(|t| is_int(&t)))
    {
        return Err(err(
            "vertex colours must be integer properties (uchar 0..255)".into(),
        ));
    }
    let scalar = props
        .iter()
        .find(|(n, p)| {
            !RESERVED.contains(&n.as_str()) && matches!(p.data_type, PropertyType::Scalar(_))
        })
        .map(|(n, _)| n.clone());
    if let Some(face) = header.elements.get("face") {
        let list = ["vertex_indices", "vertex_index"]
            .iter()
            .find_map(|n| face.properties.get(*n));
        match list.map(|p| &p.data_type) {
            Some(PropertyType::List(_, t)) if is_int(t) => {}
            Some(_) => {
                return Err(err(
                    "face `vertex_indices` must be a list of integers".into()
                ));
            }
            None if face.count == 0 => {}
            None => return Err(err("face element lacks a `vertex_indices` list".into())),
        }
    }
    Ok(VertexLayout {
        normals,
        colors,
        scalar,
    })
}

fn ply_err(path: &Path, e: &ply_rs::parser::ParseError) -> IoError {
    IoError::Ply {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Reads a PLY cloud or mesh (see the module docs for what is accepted).
pub fn read_ply(path: impl AsRef<Path>) -> Result<PlyData> {
    read_ply_with_limits(path, &Limits::default())
}

/// [`read_ply`] within `limits`: element counts are checked from the header, before any
/// element is read (and, for a regular file, against the file's length).
pub fn read_ply_with_limits(path: impl AsRef<Path>, limits: &Limits) -> Result<PlyData> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let meta = file.metadata().map_err(|e| IoError::io(path, e))?;
    let file_len = meta.is_file().then_some(meta.len());
    let mut reader = Reader::new(BufReader::with_capacity(1 << 20, file));
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| ply_err(path, &e))?;
    let layout = check_header(path, &header, file_len, limits)?;

    let mut data = PlyData::default();
    for (name, element) in &header.elements {
        match name.as_str() {
            "vertex" => {
                let verts = Parser::<VertexIn>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| ply_err(path, &e))?;
                data.positions = verts.iter().map(|v| v.p).collect();
                if layout.normals {
                    data.normals = Some(verts.iter().map(|v| v.n).collect());
                }
                if layout.colors {
                    data.colors = Some(verts.iter().map(|v| v.c).collect());
                }
                if let Some(name) = &layout.scalar {
                    data.scalar = Some(VertexScalar {
                        name: name.clone(),
                        values: verts.iter().map(|v| v.s).collect(),
                    });
                }
            }
            "face" => {
                let faces = Parser::<FaceIn>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| ply_err(path, &e))?;
                data.faces.reserve(faces.len());
                for (i, f) in faces.iter().enumerate() {
                    if f.negative {
                        return Err(IoError::Ply {
                            path: path.to_path_buf(),
                            message: format!("face {i} has a negative vertex index"),
                        });
                    }
                    if f.len != 3 {
                        return Err(IoError::Ply {
                            path: path.to_path_buf(),
                            message: format!(
                                "face {i} has {} vertices; only triangles are supported",
                                f.len
                            ),
                        });
                    }
                    data.faces.push(f.idx);
                }
            }
            _ => {
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| ply_err(path, &e))?;
            }
        }
    }
    data.validate().map_err(|m| IoError::Ply {
        path: path.to_path_buf(),
        message: m,
    })?;
    Ok(data)
}
