//! Mutation fuzzing of every reader sinew has — OBJ, STL, RON scenes, import
//! recipes, MJCF — and of the solver on random valid-but-extreme settings.
//! Each harness mutates valid seed files (bytes flipped, inserted, deleted,
//! repeated; numbers replaced by extreme values) and hands them to the
//! reader; any panic, and any input taking over 10 s, is a finding, saved
//! with its input. Readers must answer with a typed error or a result,
//! never panic.
//!
//! Each harness runs `SINEW_FUZZ_SECONDS` seconds (default 2, what the test
//! suite and CI spend). A long run, one reader at a time:
//!
//! ```text
//! SINEW_FUZZ_SECONDS=600 cargo test --release -p sinew_core --test fuzz -- --test-threads 1 --nocapture
//! ```
//!
//! It prints the executions per reader; findings go to
//! `$TMPDIR/sinew_fuzz_findings/`, each to become a regression test.
//! `SINEW_FUZZ_SEED` (an integer, default 0: the stream CI runs) starts the
//! mutations elsewhere, so a long run explores inputs CI never tries. Build
//! the long run with overflow checks on, as CI's debug build has them, at
//! release speed:
//!
//! ```text
//! CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS=true CARGO_PROFILE_RELEASE_DEBUG_ASSERTIONS=true \
//!   SINEW_FUZZ_SEED=7 SINEW_FUZZ_SECONDS=600 cargo test --release -p sinew_core --test fuzz -- --test-threads 1 --nocapture
//! ```

use sinew_core::import::ImportRecipe;
use sinew_core::import::mjcf::MjcfModel;
use sinew_core::mesh::{LoadOptions, load_mesh};
use sinew_core::scene::{Scene, builtin};
use sinew_core::{ColorScope, SolverMethod};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::{Duration, Instant};

/// An input that takes longer than this to read (and build and step) is a
/// finding: a user would take it for a hang.
const SLOW: Duration = Duration::from_secs(10);

/// xorshift64*: a small, seeded generator (the runs are reproducible).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Tokens mutations insert: extreme numbers and the syntax of the formats.
const TOKENS: &[&str] = &[
    "NaN",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e30",
    "-1e-30",
    "4294967296",
    "99999999999",
    "1.5",
    "(",
    ")",
    "[",
    "]",
    "{",
    "}",
    ",",
    ":",
    "\"",
    "Some(",
    "None",
    "<",
    ">",
    "/>",
    "</body>",
    "<body>",
    "=\"",
    "f ",
    "v ",
    "\n",
    "solid",
    "facet",
    "vertex",
    "endloop",
    "//",
    "#",
];

/// One to four mutations of `input`.
fn mutate(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(out.len() + 1);
        match rng.below(6) {
            0 if !out.is_empty() => {
                let i = at.min(out.len() - 1);
                out[i] ^= 1 << rng.below(8);
            }
            1 => {
                let token = TOKENS[rng.below(TOKENS.len())].as_bytes();
                out.splice(at..at, token.iter().copied());
            }
            2 => {
                let end = (at + 1 + rng.below(16)).min(out.len());
                out.drain(at.min(end)..end);
            }
            3 => {
                let end = (at + 1 + rng.below(64)).min(out.len());
                let piece = out[at.min(end)..end].to_vec();
                out.splice(at..at, piece);
            }
            4 => replace_number(rng, &mut out, at),
            _ => out.truncate(at),
        }
    }
    out
}

/// Replaces the number at or after `at` by an extreme value.
fn replace_number(rng: &mut Rng, out: &mut Vec<u8>, at: usize) {
    let is_number = |b: u8| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'e';
    let Some(start) = (at..out.len()).find(|&i| out[i].is_ascii_digit()) else {
        return;
    };
    let end = (start..out.len())
        .find(|&i| !is_number(out[i]))
        .unwrap_or(out.len());
    let token = [
        "NaN",
        "-1",
        "0",
        "1e30",
        "4294967295",
        "-0",
        "1e-40",
        "65536",
    ][rng.below(8)];
    out.splice(start..end, token.bytes());
}

/// Runs `read` on mutations of `seeds` for the time budget; returns the
/// executions and the findings (panics, with their inputs saved).
fn fuzz(
    name: &str,
    extension: &str,
    seeds: &[Vec<u8>],
    read: impl Fn(&Path),
) -> (u64, Vec<String>) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_fuzz_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let findings_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("sinew_fuzz_findings");
    let path = dir.join(format!("input.{extension}"));
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ name.len() as u64 ^ seed().rotate_left(17));
    let mut corpus: Vec<Vec<u8>> = seeds.to_vec();
    let (mut executions, mut findings) = (0u64, Vec::new());
    let deadline = Instant::now() + Duration::from_secs_f64(budget());
    while Instant::now() < deadline {
        let parent = &corpus[rng.below(corpus.len())];
        let input = mutate(&mut rng, parent);
        std::fs::write(&path, &input).unwrap();
        executions += 1;
        let started = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| read(&path)));
        let took = started.elapsed();
        if took > SLOW {
            // Not a crash, but a user would take it for a hang.
            std::fs::create_dir_all(&findings_dir).unwrap();
            let saved = findings_dir.join(format!("{name}_slow_{}.{extension}", findings.len()));
            std::fs::write(&saved, &input).unwrap();
            findings.push(format!("{name}: took {took:.1?} ({})", saved.display()));
        }
        if let Err(panic) = outcome {
            let message = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            std::fs::create_dir_all(&findings_dir).unwrap();
            let saved = findings_dir.join(format!("{name}_{}.{extension}", findings.len()));
            std::fs::write(&saved, &input).unwrap();
            findings.push(format!("{name}: {message} ({})", saved.display()));
        } else if corpus.len() < 64 && rng.below(8) == 0 {
            // Keep some mutants as parents: mutations build on each other.
            corpus.push(input);
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    println!(
        "fuzz {name}: {executions} executions, {} findings",
        findings.len()
    );
    (executions, findings)
}

/// `SINEW_FUZZ_SECONDS`, each harness's time budget (2 s when unset: what
/// the test suite and CI spend).
fn budget() -> f64 {
    std::env::var("SINEW_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2.0)
}

/// `SINEW_FUZZ_SEED`, mixed into every harness's random stream (0 when
/// unset: the stream the test suite runs).
fn seed() -> u64 {
    std::env::var("SINEW_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0)
}

/// Held by the harness that has the panic hook silenced (the hook is the
/// process's: harnesses running on parallel test threads take turns).
static SILENCED: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs a harness with panic messages silenced; fails on any finding.
fn run(name: &str, extension: &str, seeds: &[Vec<u8>], read: impl Fn(&Path)) {
    let turn = SILENCED.lock().unwrap_or_else(|e| e.into_inner());
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let (executions, findings) = fuzz(name, extension, seeds, read);
    std::panic::set_hook(hook);
    drop(turn);
    assert!(executions > 0);
    assert!(findings.is_empty(), "{}", findings.join("\n"));
}

const CUBE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
const TETRA: [[[f32; 3]; 3]; 4] = [
    [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
    [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
];

/// A mesh read, then built into a muscle when it loads.
fn read_mesh(path: &Path) {
    if let Ok(mesh) = load_mesh(path, &LoadOptions::default()) {
        let mut solver = sinew_core::Solver::new(Default::default()).unwrap();
        let desc = sinew_core::muscle::MuscleDesc {
            name: "fuzzed".into(),
            mesh,
            roots: sinew_core::muscle::Roots::LongestAxisTips,
            attachments: Vec::new(),
            targets: Vec::new(),
            params: Default::default(),
            maps: Default::default(),
            binding: None,
        };
        if solver.add_muscle(desc).is_ok() {
            solver.step();
        }
    }
}

#[test]
fn obj_reader() {
    let seeds = [
        CUBE.as_bytes().to_vec(),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1 2//1 -1\n".to_vec(),
    ];
    run("obj", "obj", &seeds, read_mesh);
}

#[test]
fn stl_reader() {
    let mut binary = vec![b' '; 80];
    binary.extend((TETRA.len() as u32).to_le_bytes());
    let mut ascii = String::from("solid t\n");
    for t in TETRA {
        binary.extend(
            [0f32; 3]
                .iter()
                .chain(t.iter().flatten())
                .flat_map(|x| x.to_le_bytes()),
        );
        binary.extend([0, 0]);
        ascii += "facet normal 0 0 0\nouter loop\n";
        for c in t {
            ascii += &format!("vertex {} {} {}\n", c[0], c[1], c[2]);
        }
        ascii += "endloop\nendfacet\n";
    }
    ascii += "endsolid t\n";
    run("stl", "stl", &[binary, ascii.into_bytes()], read_mesh);
}

#[test]
fn scene_reader() {
    let seeds: Vec<Vec<u8>> = ["P1", "P3"]
        .iter()
        .map(|n| builtin(n).unwrap().to_ron().unwrap().into_bytes())
        .collect();
    run("scene", "ron", &seeds, |path| {
        if let Ok(scene) = Scene::load(path)
            && let Ok(mut solver) = scene.instantiate(path.parent().unwrap())
        {
            solver.step();
        }
    });
}

#[test]
fn recipe_reader() {
    let recipe = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/recipes/t5.ron");
    let seeds = [std::fs::read(recipe).unwrap()];
    run("recipe", "ron", &seeds, |path| {
        drop(ImportRecipe::load(path))
    });
}

const MJCF: &str = r#"<mujoco model="fuzz">
  <compiler angle="degree"/>
  <default><joint damping="1"/><default class="arm"><site size="0.01"/></default></default>
  <worldbody>
    <body name="upper" pos="0 0 1" euler="0 90 0">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-90 90"/>
      <site name="origin" pos="0 0 0.05" class="arm"/>
      <body name="lower" pos="0 0 -0.3" quat="1 0 0 0">
        <joint name="elbow" type="hinge" axis="1 0 0"/>
        <site name="insertion" pos="0 0.01 -0.05"/>
      </body>
    </body>
  </worldbody>
  <tendon><spatial name="flexor"><site site="origin"/><site site="insertion"/></spatial></tendon>
  <equality><joint joint1="elbow" joint2="shoulder" polycoef="0 1 0 0 0"/></equality>
  <actuator><general name="flexor" tendon="flexor"/></actuator>
</mujoco>"#;

#[test]
fn mjcf_reader() {
    run("mjcf", "xml", &[MJCF.as_bytes().to_vec()], |path| {
        if let Ok(model) = MjcfModel::load(path) {
            for t in 0..model.tendons.len() {
                drop(model.tendon_sites(t));
            }
        }
    });
}

/// The solver on random settings inside their valid ranges, extremes
/// included: it must step without panicking (a blow-up is the run-time
/// guard's to catch and report).
#[test]
fn solver_on_extreme_settings() {
    let mut rng = Rng(0x5eed ^ seed().rotate_left(17));
    let deadline = Instant::now() + Duration::from_secs_f64(budget());
    let base = builtin("P3").unwrap();
    let mut executions = 0;
    // Log-uniform in [lo, hi].
    let pick = |rng: &mut Rng, lo: f32, hi: f32| lo * (hi / lo).powf(rng.unit());
    while Instant::now() < deadline {
        let mut scene = base.clone();
        let s = &mut scene.settings;
        s.dt = pick(&mut rng, 1e-5, 1.0);
        s.iterations = 1 + rng.below(40) as u32;
        s.substeps = 1 + rng.below(4) as u32;
        s.gravity = sinew_core::glam::Vec3::new(0.0, -pick(&mut rng, 1e-3, 1000.0), 0.0);
        s.time_scale = pick(&mut rng, 1e-3, 100.0);
        s.length_unit = pick(&mut rng, 1e-3, 1e3);
        s.threads = rng.below(4) as u32;
        s.full_search_interval = 1 + rng.below(32) as u32;
        s.choose_interval = 1 + rng.below(8) as u32;
        s.parallel_threshold = [0, 1, 8192][rng.below(3)];
        s.max_speed = pick(&mut rng, 1e-3, 1e6);
        s.method = [
            SolverMethod::Sequential,
            SolverMethod::Colored {
                scope: [ColorScope::PerMuscle, ColorScope::Global][rng.below(2)],
            },
            SolverMethod::Jacobi {
                omega: 1.0 + rng.unit(),
            },
            SolverMethod::Hybrid {
                min_group: 1 + rng.below(64) as u32,
                omega: 1.0 + rng.unit(),
            },
        ][rng.below(4)];
        for m in &mut scene.muscles {
            m.params.damping = pick(&mut rng, 1e-3, 1000.0);
            m.params.compliance.fiber = [0.0, 1e-9, 1.0][rng.below(3)];
            m.params.activation = rng.unit();
        }
        let mut solver = scene.instantiate(Path::new(".")).unwrap();
        for _ in 0..3 {
            solver.step();
        }
        assert!(
            solver
                .muscles()
                .iter()
                .all(|m| m.x.iter().all(|p| p.is_finite()))
        );
        executions += 1;
    }
    println!("fuzz solver settings: {executions} executions, 0 findings");
    assert!(executions > 0);
}

#[test]
fn mutations_change_their_input() {
    let mut rng = Rng(1);
    let seed = CUBE.as_bytes();
    let changed = (0..100).filter(|_| mutate(&mut rng, seed) != seed).count();
    assert!(changed > 90, "{changed} of 100 mutants differ");
}
