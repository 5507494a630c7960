//! The bad-input catalogue: files a user (or a hostile one) could hand
//! sinew — scenes, meshes, MJCF models, import recipes, rig maps — each with
//! what sinew must answer. Every entry must be refused with a typed error
//! whose message names the file or the element and the reason; none may
//! panic, hang or be accepted. Each runs on its own thread with a time limit.
//!
//! To add an entry: a name, the file's extension, its content, and the
//! words its error must contain.

use sinew_core::character::fit::RigMap;
use sinew_core::import::ImportRecipe;
use sinew_core::import::mjcf::MjcfModel;
use sinew_core::mesh::{LoadOptions, load_mesh};
use sinew_core::scene::{Scene, builtin};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// Which reader a catalogue entry goes through.
#[derive(Clone, Copy, Debug)]
enum Reader {
    /// `Scene::load`, then `instantiate` (meshes relative to the file).
    Scene,
    /// `load_mesh`, then a one-muscle scene built on it.
    Mesh,
    /// `MjcfModel::load`.
    Mjcf,
    /// `ImportRecipe::load`.
    Recipe,
    /// `RigMap::load`.
    RigMap,
}

/// One bad input.
struct Case {
    name: &'static str,
    reader: Reader,
    extension: &'static str,
    content: Vec<u8>,
    /// Every one of these must appear in the error message.
    expect: Vec<&'static str>,
}

/// The P1 scene as RON: the text scene entries edit.
fn p1() -> String {
    builtin("P1").unwrap().to_ron().unwrap()
}

/// P1 with each `(from, to)` replaced once; `from` must be in the text (so
/// an entry cannot silently stop testing what it says).
fn edit(edits: &[(&str, &str)]) -> Vec<u8> {
    let mut text = p1();
    for (from, to) in edits {
        assert!(text.contains(from), "'{from}' is not in P1's RON");
        text = text.replacen(from, to, 1);
    }
    text.into_bytes()
}

fn scene(name: &'static str, edits: &[(&str, &str)], expect: &[&'static str]) -> Case {
    Case {
        name,
        reader: Reader::Scene,
        extension: "ron",
        content: edit(edits),
        expect: expect.to_vec(),
    }
}

fn file(
    name: &'static str,
    reader: Reader,
    extension: &'static str,
    content: impl Into<Vec<u8>>,
    expect: &[&'static str],
) -> Case {
    Case {
        name,
        reader,
        extension,
        content: content.into(),
        expect: expect.to_vec(),
    }
}

const TRACK: &str = "track: TransformTrack(\n                keys: [],";
const ACTIVATION: &str = "activation: None,";
const ORDER: &str = "            Area,\n            Volume,\n        ],";

fn track(keys: &str) -> String {
    format!("track: TransformTrack(\n                keys: [{keys}],")
}

fn key(time: &str, translation: &str, rotation: &str) -> String {
    format!("(time: {time}, translation: ({translation}), rotation: ({rotation})),")
}

fn curve(keys: &str) -> String {
    format!("activation: Some(Curve(keys: [{keys}])),")
}

/// A linear sensor `s` on `bone` at `point`.
fn sensor(point: &str, bone: &str) -> String {
    format!("sensors: [(name: \"s\", kind: Linear(point: (bone: \"{bone}\", point: {point})))],")
}

/// The muscle driven by one activation layer.
fn drive(layer: &str) -> String {
    format!("drive: [{layer}],")
}

/// A skeleton of one body `b` with `joints`, and `rest` (motion, couplings).
fn skeleton(joints: &str, rest: &str) -> String {
    format!("skeleton: Some(Skeleton(bodies: [(name: \"b\", {joints})], {rest})),")
}

/// P1 with `projection_order: [order]`.
fn with_order(order: &str) -> String {
    let text = p1();
    let start = text.find("projection_order: [").unwrap() + "projection_order: [".len();
    let end = start + text[start..].find(']').unwrap();
    format!("{}{order}{}", &text[..start], &text[end..])
}

/// P1 with its muscle's mesh read from `path`.
fn with_mesh_file(path: &str) -> String {
    let mut scene = builtin("P1").unwrap();
    scene.muscles[0].mesh = sinew_core::scene::MeshSource::File {
        path: path.into(),
        triangulate: false,
        scale: 1.0,
        orient_outward: false,
        translation: sinew_core::glam::Vec3::ZERO,
    };
    scene.to_ron().unwrap()
}

#[rustfmt::skip]
fn scene_cases() -> Vec<Case> {
    let identity = "0, 0, 0, 1";
    let unsorted = track(&(key("1", "0, 0, 0", identity) + &key("0", "0, 0, 0", identity)));
    let nan_key = track(&key("0", "NaN, 0, 0", identity));
    let nan_time = track(&key("NaN", "0, 0, 0", identity));
    let zero_rotation = track(&key("0", "0, 0, 0", "0, 0, 0, 0"));
    let inf_rotation = track(&key("0", "0, 0, 0", "inf, 0, 0, 1"));
    let (c_unsorted, c_repeat) = (curve("(1, 0.5), (0, 0.1)"), curve("(0, 0.5), (0, 0.1)"));
    let (c_nan_time, c_nan_value) = (curve("(NaN, 0.5)"), curve("(0, NaN)"));
    let (c_high, c_negative, c_empty) = (curve("(0, 1.5)"), curve("(0, -0.2)"), curve(""));
    let settings = "SolverSettings";
    vec![
        scene("typo in a setting", &[("iterations: 5,", "iteratons: 5,")], &["`iteratons`", settings, "did you mean `iterations`"]),
        scene("typo in the muscle list", &[("muscles: [", "muscels: [")], &["`muscels`", "did you mean `muscles`"]),
        scene("unknown parameter", &[("max_contraction: 0.35,", "max_contraction: 0.35, stiffness: 3,")], &["`stiffness`", "MuscleParams", "expected one of"]),
        scene("typo in a compliance", &[("sliding: 0.001,", "slidng: 0.001,")], &["`slidng`", "did you mean `sliding`"]),
        scene("typo in a bone", &[("body: None,", "bdy: None,")], &["`bdy`", "did you mean `body`"]),
        scene("typo in an attachment", &[("vertex: Some(0),", "vertx: Some(0),")], &["`vertx`", "did you mean `vertex`"]),
        scene("typo in volume parameters", &[("activation_gain: 1.2,", "activation_gian: 1.2,")], &["`activation_gian`", "did you mean `activation_gain`"]),
        scene("unknown method", &[("method: Sequential,", "method: Sequental,")], &["`Sequental`", "did you mean `Sequential`"]),
        scene("unknown constraint in the order", &[(ORDER, "            Area,\n            Volum,\n        ],")], &["`Volum`", "did you mean `Volume`"]),
        file("empty projection order", Reader::Scene, "ron", with_order(""), &["projection_order", "missing [Attach, BranchAttach"]),
        scene("projection order missing types", &[(ORDER, "        ],")], &["projection_order", "missing [Area, Volume]"]),
        scene("Volume listed three times", &[(ORDER, "            Area,\n            Volume,\n            Volume,\n            Volume,\n        ],")], &["projection_order", "repeated [Volume]"]),
        scene("zero time step", &[("dt: 0.016666668,", "dt: 0.0,")], &["dt = 0", "> 0"]),
        scene("negative time step", &[("dt: 0.016666668,", "dt: -0.01,")], &["dt = -0.01"]),
        scene("NaN time step", &[("dt: 0.016666668,", "dt: NaN,")], &["dt = NaN"]),
        scene("a ten-second frame", &[("dt: 0.016666668,", "dt: 10.0,")], &["dt = 10", "at most 1 s"]),
        scene("zero iterations", &[("iterations: 5,", "iterations: 0,")], &["iterations = 0"]),
        scene("a million iterations", &[("iterations: 5,", "iterations: 1000000,")], &["iterations = 1000000", "[1, 10000]"]),
        scene("zero substeps", &[("substeps: 1,", "substeps: 0,")], &["substeps = 0"]),
        scene("100 000 threads", &[("threads: 0,", "threads: 100000,")], &["threads = 100000", "[0, 1024]"]),
        scene("negative threads", &[("threads: 0,", "threads: -1,")], &["33:", "out of range"]),
        scene("gravity 1e9", &[("gravity: Vec3(0.0, -9.81, 0.0)", "gravity: Vec3(0.0, -1e9, 0.0)")], &["gravity", "1000 m/s²"]),
        scene("NaN gravity", &[("gravity: Vec3(0.0, -9.81, 0.0)", "gravity: Vec3(0.0, NaN, 0.0)")], &["gravity = NaN"]),
        scene("zero length unit", &[("length_unit: 1.0,", "length_unit: 0.0,")], &["length_unit = 0"]),
        scene("negative time scale", &[("time_scale: 1.0,", "time_scale: -1.0,")], &["time_scale = -1"]),
        scene("zero search interval", &[("full_search_interval: 16,", "full_search_interval: 0,")], &["full_search_interval = 0"]),
        scene("zero choose interval", &[("choose_interval: 4,", "choose_interval: 0,")], &["choose_interval = 0"]),
        scene("zero bone contact interval", &[("bone_contact_interval: 1,", "bone_contact_interval: 0,")], &["bone_contact_interval = 0"]),
        scene("zero walk interval", &[("walk_interval: 1,", "walk_interval: 0,")], &["walk_interval = 0"]),
        scene("negative walk interval", &[("walk_interval: 1,", "walk_interval: -2,")], &["walk_interval", "true / false"]),
        scene("zero snapshot interval", &[("snapshot_interval: 1,", "snapshot_interval: 0,")], &["snapshot_interval = 0"]),
        scene("activation 1.5", &[("activation: 0.0,", "activation: 1.5,")], &["muscle 'oval'", "activation = 1.5", "[0, 1]"]),
        scene("activation 5", &[("activation: 0.0,", "activation: 5.0,")], &["activation = 5"]),
        scene("negative activation", &[("activation: 0.0,", "activation: -0.5,")], &["activation = -0.5"]),
        scene("rest activation 2", &[("rest_activation: 0.0,", "rest_activation: 2.0,")], &["rest_activation = 2"]),
        scene("contraction over 100 %", &[("max_contraction: 0.35,", "max_contraction: 2.0,")], &["max_contraction = 2"]),
        scene("negative compliance", &[("bind: 0.05,", "bind: -0.05,")], &["compliance.Bind = -0.05"]),
        scene("NaN compliance", &[("sliding: 0.001,", "sliding: NaN,")], &["compliance.Sliding = NaN"]),
        scene("negative volume gain", &[("gain: 1.0,", "gain: -1.0,")], &["volume.gain = -1"]),
        scene("negative activation gain", &[("activation_gain: 1.2,", "activation_gain: -1.2,")], &["volume.activation_gain = -1.2"]),
        scene("NaN damping", &[("damping: 3.08,", "damping: NaN,")], &["damping = NaN"]),
        scene("damping 1e6", &[("damping: 3.08,", "damping: 1e6,")], &["damping = 1000000"]),
        scene("zero density", &[("mass: Density(1060.0),", "mass: Density(0.0),")], &["mass = 0"]),
        scene("negative weight", &[("sliding: 1.0,", "sliding: -1.0,")], &["weights.sliding = -1"]),
        scene("NaN contact reach", &[("contact_reach: 0.003,", "contact_reach: NaN,")], &["contact_reach = NaN"]),
        scene("zero muscle iterations", &[("iterations: None,", "iterations: Some(0),")], &["iterations = 0", "muscle 'oval'"]),
        scene("a million smoothing passes", &[("fiber_smoothing: 3,", "fiber_smoothing: 1000000,")], &["fiber_smoothing = 1000000"]),
        scene("unsorted activation keys", &[(ACTIVATION, &c_unsorted)], &["muscle 'oval' activation", "key 1", "sorted"]),
        scene("repeated activation key time", &[(ACTIVATION, &c_repeat)], &["muscle 'oval' activation", "key 1", "without repeats"]),
        scene("NaN activation key time", &[(ACTIVATION, &c_nan_time)], &["key 0 has time NaN"]),
        scene("NaN activation value", &[(ACTIVATION, &c_nan_value)], &["key 0", "value NaN"]),
        scene("activation key 1.5", &[(ACTIVATION, &c_high)], &["key 0", "value 1.5", "[0, 1]"]),
        scene("negative activation key", &[(ACTIVATION, &c_negative)], &["value -0.2"]),
        scene("empty activation curve", &[(ACTIVATION, &c_empty)], &["muscle 'oval' activation", "no keys"]),
        scene("unsorted bone track", &[(TRACK, &unsorted)], &["bone 'ground' track", "key 1", "sorted"]),
        scene("NaN bone translation", &[(TRACK, &nan_key)], &["bone 'ground' track", "key 0", "NaN"]),
        scene("NaN bone key time", &[(TRACK, &nan_time)], &["bone 'ground' track", "time NaN"]),
        scene("zero rotation", &[(TRACK, &zero_rotation)], &["bone 'ground' track", "length 0"]),
        scene("infinite rotation", &[(TRACK, &inf_rotation)], &["bone 'ground' track", "unit quaternion"]),
        scene("attachment past the mesh", &[("vertex: Some(91),", "vertex: Some(9100),")], &["attachment 1", "vertex 9100", "92 vertices"]),
        scene("attachment to a missing bone", &[("bone: None,\n                    vertex: Some(91)", "bone: Some(\"femur\"),\n                    vertex: Some(91)")], &["attachment 1", "unknown bone 'femur'"]),
        scene("NaN attachment point", &[("vertex: Some(91),\n                    point: None,", "vertex: None,\n                    point: Some((NaN, 0, 0)),")], &["attachment 1", "point"]),
        scene("negative attachment radius", &[("vertex: Some(91),", "vertex: Some(91), radius: -1.0,")], &["attachment 1", "radius -1"]),
        scene("missing target", &[("\"ground\",\n            ],", "\"floor\",\n            ],")], &["target 0", "unknown target 'floor'"]),
        scene("two things named alike", &[("name: \"oval\"", "name: \"ground\"")], &["duplicate name 'ground'"]),
        scene("zero plane normal", &[("normal: Vec3(0.0, 1.0, 0.0)", "normal: Vec3(0.0, 0.0, 0.0)")], &["bone 'ground' plane", "zero length"]),
        scene("NaN plane size", &[("size: 0.4", "size: NaN")], &["bone 'ground' plane", "size NaN"]),
        scene("negative ellipsoid radius", &[("radii: Vec3(0.06, 0.025, 0.025)", "radii: Vec3(-0.06, 0.025, 0.025)")], &["<generated oval>", "radii > 0"]),
        scene("NaN ellipsoid centre", &[("center: Vec3(0.0, 0.0, 0.0),\n                radii", "center: Vec3(NaN, 0.0, 0.0),\n                radii")], &["<generated oval>", "expected finite"]),
        scene("ellipsoid with 0 segments", &[("segments: 10,", "segments: 0,")], &["<generated oval>", "segments ≥ 3"]),
        scene("ellipsoid of 270 000 vertices (fuzzing: a 786 000-vertex build ran 20 min)", &[("segments: 10,", "segments: 30000,")], &["<generated oval>", "about 270002 vertices"]),
        scene("ellipsoid of 4e9 segments", &[("segments: 10,", "segments: 4000000000,")], &["<generated oval>", "more than the 200000"]),
        file("missing mesh file", Reader::Scene, "ron", with_mesh_file("nope.obj"), &["nope.obj", "cannot read"]),
        file("NaN mesh translation", Reader::Scene, "ron", with_mesh_file("m.obj").replace("path: \"m.obj\",", "path: \"m.obj\", translation: Vec3(NaN, 0, 0),"), &["muscle 'oval' mesh", "translation", "not finite"]),
        scene("skeleton body its own parent", &[("skeleton: None,", "skeleton: Some(Skeleton(bodies: [(name: \"a\", parent: Some(\"a\"))])),")], &["skeleton body 0 'a'", "parent 'a'"]),
        scene("skeleton body parent listed later", &[("skeleton: None,", "skeleton: Some(Skeleton(bodies: [(name: \"a\", parent: Some(\"b\")), (name: \"b\", parent: Some(\"a\"))])),")], &["skeleton body 0 'a'", "parent 'b'"]),
        scene("bone following a missing body", &[("body: None,", "body: Some(\"pelvis\"),")], &["bone 'ground'", "unknown skeleton body 'pelvis'"]),
        scene("sensor at a NaN point", &[("sensors: [],", &sensor("(NaN, 0, 0)", "ground"))], &["sensor 0 's'", "non-finite point"]),
        scene("sensor on a missing bone", &[("sensors: [],", &sensor("(0, 0, 0)", "radius"))], &["unknown bone 'radius'"]),
        scene("drive reading a missing sensor", &[("drive: [],", &drive("Add(Sensor((sensor: \"s\")))"))], &["activation layer 0", "unknown sensor 's'"]),
        scene("drive with a NaN constant", &[("drive: [],", &drive("Add(Constant(NaN))"))], &["activation layer 0", "constant NaN"]),
        scene("drive curve out of order", &[("drive: [],", &drive("Add(Curve((keys: [(1, 0), (0, 1)])))"))], &["activation layer 0", "curve", "sorted"]),
        scene("drive clamp that is empty", &[("drive: [],", &drive("Clamp(min: 1, max: 0)"))], &["activation layer 0", "is empty"]),
        scene("trigger with a negative attack", &[("sensors: [],", &sensor("(0, 0, 0)", "ground")), ("drive: [],", &drive("Add(Sensor((sensor: \"s\", trigger: (attack: -1))))"))], &["activation layer 0", "attack"]),
        scene("trigger gate closing above opening", &[("sensors: [],", &sensor("(0, 0, 0)", "ground")), ("drive: [],", &drive("Add(Sensor((sensor: \"s\", trigger: (threshold_on: 0.1, threshold_off: 0.5))))"))], &["threshold_off 0.5 > threshold_on 0.1"]),
        scene("remap ramp of repeated keys", &[("sensors: [],", &sensor("(0, 0, 0)", "ground")), ("drive: [],", &drive("Add(Sensor((sensor: \"s\", remap: (ramp: Some((keys: [(0, 0), (0, 1)]))))))"))], &["remap ramp", "without repeats"]),
        scene("joint with a zero axis", &[("skeleton: None,", &skeleton("joints: [(name: \"j\", kind: Hinge, axis: (0, 0, 0))]", ""))], &["joint 'j'", "axis has zero length"]),
        scene("joint with a reversed range", &[("skeleton: None,", &skeleton("joints: [(name: \"j\", kind: Hinge, axis: (0, 0, 1), range: Some((1, -1)))]", ""))], &["joint 'j'", "range (1, -1) is empty"]),
        scene("motion of a missing joint", &[("skeleton: None,", &skeleton("", "motion: [(joint: \"knee\", curve: (keys: [(0, 0)]))]"))], &["skeleton motion 0", "unknown joint 'knee'"]),
        scene("motion keys out of order", &[("skeleton: None,", &skeleton("joints: [(name: \"j\", kind: Hinge, axis: (0, 0, 1))]", "motion: [(joint: \"j\", curve: (keys: [(1, 0), (0, 1)]))]"))], &["skeleton motion 0 (joint 'j')", "sorted"]),
        scene("coupling with a NaN coefficient", &[("skeleton: None,", &skeleton("joints: [(name: \"j\", kind: Hinge, axis: (0, 0, 1))]", "couplings: [(joint: \"j\", polynomial: (NaN, 0, 0, 0, 0))]"))], &["skeleton coupling 0", "non-finite"]),
        file("empty scene file", Reader::Scene, "ron", "", &["1:1", "Scene"]),
        file("truncated scene", Reader::Scene, "ron", p1()[..900].to_string(), &["truncated scene"]),
        file("not RON at all", Reader::Scene, "ron", "{\"name\": \"json\"}", &["1:1"]),
        file("binary garbage", Reader::Scene, "ron", vec![0xff, 0xfe, 0x00, 0x81, 0x02], &["binary garbage"]),
    ]
}

const CUBE_VERTICES: &str =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";
const CUBE_FACES: &str = "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
const CUBE_FACES_INWARD: &str =
    "f 2 3 4 1\nf 8 7 6 5\nf 5 6 2 1\nf 6 7 3 2\nf 7 8 4 3\nf 8 5 1 4\n";

/// A binary STL whose header counts `count` triangles, holding `held`.
fn stl(count: u32, held: usize) -> Vec<u8> {
    let mut bytes = vec![b' '; 80];
    bytes.extend(count.to_le_bytes());
    for _ in 0..held {
        let corners = [
            0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ];
        bytes.extend(corners.iter().flat_map(|x| x.to_le_bytes()));
        bytes.extend([0, 0]);
    }
    bytes
}

#[rustfmt::skip]
fn mesh_cases() -> Vec<Case> {
    let cube = |faces: &str| format!("{CUBE_VERTICES}{faces}");
    vec![
        file("OBJ without faces", Reader::Mesh, "obj", CUBE_VERTICES, &["no faces"]),
        file("OBJ with a NaN vertex", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("v 1 0 0", "v 1 nan 0", 1), &["vertex 1", "non-finite"]),
        file("OBJ face past the vertices", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("f 1 4 3 2", "f 1 4 3 20", 1), &["face 0", "vertex 19", "8 vertices"]),
        file("OBJ face index 0", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("f 1 4 3 2", "f 0 4 3 2", 1), &["line 9"]),
        file("OBJ with a word for a coordinate", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("v 1 1 0", "v 1 one 0", 1), &["line 3"]),
        file("OBJ two-corner face", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("f 1 4 3 2", "f 1 4", 1), &["line 9", "2 vertices"]),
        file("OBJ open box", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("f 1 4 3 2\n", "", 1), &["open", "open edges"]),
        file("OBJ non-manifold edge", Reader::Mesh, "obj", cube(CUBE_FACES) + "v 2 0 0\nf 1 2 9\n", &["non-manifold"]),
        file("OBJ inconsistently oriented", Reader::Mesh, "obj", cube(CUBE_FACES).replacen("f 1 4 3 2", "f 2 3 4 1", 1), &["inconsistently oriented"]),
        file("OBJ with every face inward", Reader::Mesh, "obj", cube(CUBE_FACES_INWARD), &["faces point inwards", "orient_outward"]),
        file("OBJ of one repeated corner", Reader::Mesh, "obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 1\n", &["face 0", "degenerate"]),
        file("STL header over-counts", Reader::Mesh, "stl", stl(5, 2), &["counts 5 triangles", "hold 2"]),
        file("STL header under-counts", Reader::Mesh, "stl", stl(1, 2), &["counts 1 triangles", "hold 2"]),
        file("STL cut mid-triangle", Reader::Mesh, "stl", stl(2, 2)[..150].to_vec(), &["counts 2 triangles"]),
        file("STL shorter than its header", Reader::Mesh, "stl", b"tiny".to_vec(), &["too short"]),
        file("ASCII STL that breaks off", Reader::Mesh, "stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", &["ASCII STL"]),
        file("unsupported mesh format", Reader::Mesh, "ply", "ply\n", &["unsupported mesh format"]),
    ]
}

#[rustfmt::skip]
fn model_cases() -> Vec<Case> {
    let deep = |n: usize| {
        let open: String = (0..n).map(|i| format!("<body name=\"b{i}\">")).collect();
        format!("<mujoco><worldbody>{open}{}</worldbody></mujoco>", "</body>".repeat(n))
    };
    vec![
        file("MJCF not XML", Reader::Mjcf, "xml", "<mujoco><worldbody>", &["malformed XML"]),
        file("MJCF bodies 10 000 deep", Reader::Mjcf, "xml", deep(10_000), &["<body>", "nested more than 256 deep"]),
        file("MJCF includes itself", Reader::Mjcf, "xml", "<mujoco><include file=\"catalogue_MJCF includes itself.xml\"/></mujoco>", &["<include>", "include cycle"]),
        file("MJCF include of a missing file", Reader::Mjcf, "xml", "<mujoco><include file=\"absent.xml\"/></mujoco>", &["<include>", "does not exist"]),
        file("MJCF include without file", Reader::Mjcf, "xml", "<mujoco><include/></mujoco>", &["<include>", "'file'"]),
        file("MJCF NaN position", Reader::Mjcf, "xml", "<mujoco><worldbody><body name=\"a\" pos=\"0 nan 0\"/></worldbody></mujoco>", &["<body>", "not a finite number"]),
        file("MJCF tendon through a missing site", Reader::Mjcf, "xml", "<mujoco><tendon><spatial name=\"t\"><site site=\"nowhere\"/></spatial></tendon></mujoco>", &["nowhere"]),
        file("recipe with a typo", Reader::Recipe, "ron", "ImportRecipe(name: \"x\", modle: \"a.xml\")", &["`modle`", "did you mean `model`"]),
        file("recipe that is not RON", Reader::Recipe, "ron", "name = x", &["1:"]),
        file("rig map with a typo", Reader::RigMap, "ron", "RigMap(pair: [])", &["`pair`", "did you mean `pairs`"]),
    ]
}

/// What reading `path` with `reader` answers: `Ok` when it was accepted.
fn read(reader: Reader, path: &Path) -> Result<(), String> {
    let dir = path.parent().unwrap();
    match reader {
        Reader::Scene => {
            let scene = Scene::load(path).map_err(|e| e.to_string())?;
            scene.instantiate(dir).map(drop).map_err(|e| e.to_string())
        }
        Reader::Mesh => {
            load_mesh(path, &LoadOptions::default()).map_err(|e| e.to_string())?;
            let mut scene = builtin("P1").unwrap();
            scene.muscles[0].mesh = sinew_core::scene::MeshSource::File {
                path: path.file_name().unwrap().to_string_lossy().into(),
                triangulate: false,
                scale: 1.0,
                orient_outward: false,
                translation: sinew_core::glam::Vec3::ZERO,
            };
            scene.muscles[0].attachments.clear();
            scene.instantiate(dir).map(drop).map_err(|e| e.to_string())
        }
        Reader::Mjcf => {
            // As `import-mjcf` does: load, then resolve every tendon's sites.
            let model = MjcfModel::load(path).map_err(|e| e.to_string())?;
            (0..model.tendons.len())
                .try_for_each(|t| model.tendon_sites(t).map(drop))
                .map_err(|e| e.to_string())
        }
        Reader::Recipe => ImportRecipe::load(path)
            .map(drop)
            .map_err(|e| e.to_string()),
        Reader::RigMap => RigMap::load(path).map(drop).map_err(|e| e.to_string()),
    }
}

#[test]
fn every_bad_input_is_refused_by_name() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_catalogue_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases: Vec<Case> = [scene_cases(), mesh_cases(), model_cases()]
        .into_iter()
        .flatten()
        .collect();
    assert!(
        cases.len() >= 60,
        "the catalogue holds {} inputs",
        cases.len()
    );
    let mut failures = Vec::new();
    for case in &cases {
        let path: PathBuf = dir.join(format!("catalogue_{}.{}", case.name, case.extension));
        std::fs::write(&path, &case.content).unwrap();
        let (sender, receiver) = mpsc::channel();
        let (reader, thread_path) = (case.reader, path.clone());
        std::thread::spawn(move || sender.send(read(reader, &thread_path)).ok());
        match receiver.recv_timeout(Duration::from_secs(60)) {
            Err(mpsc::RecvTimeoutError::Timeout) => failures.push(format!("{}: hangs", case.name)),
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                failures.push(format!("{}: panicked", case.name))
            }
            Ok(Ok(())) => failures.push(format!("{}: silently accepted", case.name)),
            Ok(Err(message)) => {
                let missing: Vec<_> = case
                    .expect
                    .iter()
                    .filter(|w| !message.contains(*w))
                    .collect();
                if !missing.is_empty() {
                    failures.push(format!("{}: `{message}` lacks {missing:?}", case.name));
                }
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        failures.is_empty(),
        "{} of {} inputs:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
