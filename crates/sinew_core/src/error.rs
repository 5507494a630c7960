//! Typed errors. Every failure names the file (or generator), the element and the reason.

use std::path::PathBuf;

/// A mesh could not be loaded or does not satisfy what the caller asked for.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be read.
    #[error("{file}: cannot read file: {source}")]
    Io {
        /// Offending file.
        file: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file extension is not one sinew reads.
    #[error("{file}: unsupported mesh format (expected .obj or .stl)")]
    UnsupportedFormat {
        /// Offending file.
        file: PathBuf,
    },
    /// The file's syntax is broken.
    #[error("{file}: parse error: {reason}")]
    Parse {
        /// Offending file.
        file: PathBuf,
        /// What the parser reported.
        reason: String,
    },
    /// An OBJ has no faces in the group asked for.
    #[error("{file}: no faces in group '{group}'")]
    MissingGroup {
        /// Offending file.
        file: PathBuf,
        /// The group's name.
        group: String,
    },
    /// The mesh has no polygons.
    #[error("{file}: mesh has no faces")]
    NoFaces {
        /// Offending file.
        file: PathBuf,
    },
    /// A coordinate is NaN or infinite.
    #[error("{file}: vertex {vertex} has a non-finite coordinate {value:?}")]
    NonFinite {
        /// Offending file.
        file: PathBuf,
        /// Vertex index (0-based, as stored in the file).
        vertex: usize,
        /// The coordinate triple.
        value: [f32; 3],
    },
    /// A face references a vertex past the end of the vertex list.
    #[error("{file}: face {face} references vertex {index}, but there are only {count} vertices")]
    IndexOutOfRange {
        /// Offending file.
        file: PathBuf,
        /// Face index.
        face: usize,
        /// The referenced vertex.
        index: usize,
        /// Number of vertices.
        count: usize,
    },
    /// A face has fewer than three distinct vertices or (near) zero area.
    #[error("{file}: face {face} is degenerate ({reason})")]
    DegenerateFace {
        /// Offending file.
        file: PathBuf,
        /// Face index.
        face: usize,
        /// Why it is degenerate.
        reason: String,
    },
    /// An edge is shared by more than two faces.
    #[error("{file}: edge ({a}, {b}) is shared by {faces} faces (non-manifold)")]
    NonManifoldEdge {
        /// Offending file.
        file: PathBuf,
        /// First vertex.
        a: u32,
        /// Second vertex.
        b: u32,
        /// Number of faces using the edge.
        faces: usize,
    },
    /// An edge borders only one face, so the surface is open.
    #[error(
        "{file}: mesh is open: edge ({a}, {b}) borders a single face ({open_edges} open edges in all)"
    )]
    Open {
        /// Offending file.
        file: PathBuf,
        /// First vertex of the first open edge.
        a: u32,
        /// Second vertex.
        b: u32,
        /// Total number of open edges.
        open_edges: usize,
    },
    /// A closed mesh's faces point inwards (its signed volume is negative):
    /// its muscle would be turned inside out by Volume and Sliding.
    #[error(
        "{file}: faces point inwards (signed volume {volume:.3e}); reverse them, or set `orient_outward: true` on the mesh file in the scene"
    )]
    InsideOut {
        /// Offending file.
        file: PathBuf,
        /// The signed volume. Units: scene units³.
        volume: f64,
    },
    /// Two faces sharing an edge traverse it in the same direction.
    #[error("{file}: faces are inconsistently oriented at edge ({a}, {b})")]
    InconsistentOrientation {
        /// Offending file.
        file: PathBuf,
        /// First vertex.
        a: u32,
        /// Second vertex.
        b: u32,
    },
}

/// A muscle could not be built from its description.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The mesh is unusable.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A root vertex index is past the end of the mesh.
    #[error("muscle '{muscle}': root vertex {vertex} is out of range (mesh has {count} vertices)")]
    RootOutOfRange {
        /// Muscle name.
        muscle: String,
        /// Offending root index.
        vertex: u32,
        /// Vertex count.
        count: usize,
    },
    /// No root vertices were given and none could be inferred.
    #[error("muscle '{muscle}': no root vertices given and none could be inferred ({reason})")]
    NoRoots {
        /// Muscle name.
        muscle: String,
        /// Why inference failed.
        reason: String,
    },
    /// A solver setting is NaN, negative or otherwise out of range.
    #[error("solver settings: {setting} = {value} is invalid ({reason})")]
    InvalidSetting {
        /// Setting name, as in the scene's `settings`.
        setting: String,
        /// Offending value.
        value: f32,
        /// What is expected.
        reason: String,
    },
    /// A muscle parameter is NaN, negative or otherwise out of range.
    #[error("muscle '{muscle}': parameter {parameter} = {value} is invalid ({reason})")]
    InvalidParameter {
        /// Muscle name.
        muscle: String,
        /// Parameter name.
        parameter: String,
        /// Offending value.
        value: f32,
        /// What is expected.
        reason: String,
    },
    /// The projection order is not a permutation of the constraint types.
    #[error(
        "solver: projection_order must list every constraint type once; missing {missing:?}, repeated {repeated:?}"
    )]
    ProjectionOrder {
        /// Types the order leaves out (they would never be projected, and a
        /// colour plan must place every constraint).
        missing: Vec<crate::muscle::ConstraintKind>,
        /// Types listed more than once.
        repeated: Vec<crate::muscle::ConstraintKind>,
    },
    /// An attachment references a vertex past the end of the mesh.
    #[error(
        "muscle '{muscle}': attachment {attachment} uses vertex {vertex}, but the mesh has {count} vertices"
    )]
    AttachmentVertexOutOfRange {
        /// Muscle name.
        muscle: String,
        /// Attachment index.
        attachment: usize,
        /// Offending vertex.
        vertex: u32,
        /// Vertex count.
        count: usize,
    },
    /// A per-vertex map has the wrong length.
    #[error(
        "muscle '{muscle}': per-vertex map '{map}' has {len} entries, mesh has {count} vertices"
    )]
    MapLength {
        /// Muscle name.
        muscle: String,
        /// Map name.
        map: String,
        /// Map length.
        len: usize,
        /// Vertex count.
        count: usize,
    },
    /// A per-vertex map holds a value out of its range (a weight below 0,
    /// a mass multiplier not above 0, anything not finite).
    #[error("muscle '{muscle}': per-vertex map '{map}' at vertex {vertex} is {value}: {reason}")]
    MapValue {
        /// Muscle name.
        muscle: String,
        /// Map name.
        map: String,
        /// The vertex.
        vertex: usize,
        /// The value (a fibre: its first non-finite component).
        value: f32,
        /// The allowed range.
        reason: String,
    },
}

/// A scene could not be read, written or instantiated.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// Offending file.
        file: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// RON syntax or schema error, with line and column.
    #[error("{file}:{line}:{column}: {reason}")]
    Syntax {
        /// Offending file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Parser message.
        reason: String,
    },
    /// The scene could not be serialised.
    #[error("cannot serialise scene: {0}")]
    Serialize(String),
    /// A name refers to a bone or muscle that does not exist.
    #[error("{context}: unknown {kind} '{name}'")]
    UnknownReference {
        /// Where the reference appears, e.g. "muscle 'biceps' attachment 0".
        context: String,
        /// "bone", "target" …
        kind: &'static str,
        /// The missing name.
        name: String,
    },
    /// Two bones or muscles share a name.
    #[error("duplicate name '{0}' (bones and muscles need unique names)")]
    DuplicateName(String),
    /// A scene value is out of range.
    #[error("{context}: {reason}")]
    Invalid {
        /// Where in the scene.
        context: String,
        /// What is wrong.
        reason: String,
    },
    /// Building a muscle failed.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// Loading a mesh failed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A scene file's content is invalid ([`crate::scene::Scene::validate`]):
    /// the error, with the file it was read from.
    #[error("{file}: {error}")]
    InFile {
        /// The scene file.
        file: PathBuf,
        /// What is wrong, naming the element.
        #[source]
        error: Box<SceneError>,
    },
}

impl SceneError {
    /// This error as found in `file`; errors that already name their file
    /// (I/O, syntax, a mesh's) are returned as they are.
    pub fn in_file(self, file: &std::path::Path) -> Self {
        match self {
            Self::Io { .. } | Self::Syntax { .. } | Self::Mesh(_) | Self::InFile { .. } => self,
            error => Self::InFile {
                file: file.to_path_buf(),
                error: Box::new(error),
            },
        }
    }
}

/// An MJCF model could not be imported, or a muscle could not be built from
/// its path.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// Offending file.
        file: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Malformed XML.
    #[error("{file}:{line}:{column}: malformed XML: {reason}")]
    Xml {
        /// Offending file.
        file: PathBuf,
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// Parser message.
        reason: String,
    },
    /// An element is valid XML but not a model sinew can use.
    #[error("{file}:{line}: <{element}>: {reason}")]
    Model {
        /// Offending file.
        file: PathBuf,
        /// 1-based line.
        line: u32,
        /// Element name.
        element: String,
        /// What is wrong.
        reason: String,
    },
    /// A muscle's path cannot make a muscle.
    #[error("muscle '{muscle}': {reason}")]
    Path {
        /// Muscle (actuator or tendon) name.
        muscle: String,
        /// What is wrong.
        reason: String,
    },
    /// A name asked for on the command line or in a recipe does not exist.
    #[error("{context}: unknown {kind} '{name}'")]
    UnknownName {
        /// Where it was asked for.
        context: String,
        /// "muscle", "site", "body" …
        kind: &'static str,
        /// The missing name.
        name: String,
    },
    /// A mesh could not be loaded or built.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The produced scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
}
