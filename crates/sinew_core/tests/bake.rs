//! Baking for DCCs: the `.pc2` caches hold exactly the solver's surfaces
//! frame by frame (in metres, whatever the scene's unit), the `.glb` holds
//! the rest meshes and one bone key per frame, and bad output folders or
//! broken caches give typed errors naming the file.

use sinew_core::bake::{Bake, BakeError, BakeFormat, ExistingFiles, GLB_FILE, obj_file_name, pc2};
use sinew_core::glam;
use sinew_core::scene::{Scene, builtin};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_bake_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The JSON chunk of a `.glb`.
fn glb_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

#[test]
fn caches_hold_every_frame_of_every_muscle_in_metres() {
    for unit in [1.0f32, 100.0] {
        // The same geometry read as metres and as centimetres: the caches
        // are the scene's positions divided by its unit.
        let mut scene = builtin("P3").unwrap();
        scene.settings.length_unit = unit;
        let mut solver = scene.instantiate(Path::new(".")).unwrap();
        let out = scratch(&format!("p3_{unit}"));
        let mut bake = Bake::start(&solver, &out, &BakeFormat::ALL).unwrap();
        let mut expected = vec![surfaces_in_metres(&solver, unit)];
        for _ in 0..5 {
            solver.step();
            bake.record(&solver).unwrap();
            expected.push(surfaces_in_metres(&solver, unit));
        }
        let files = bake.finish().unwrap();
        assert_eq!(files.len(), 6 + solver.muscles().len() + 1, "{files:?}");
        assert!(out.join(obj_file_name(5)).exists());
        for (m, muscle) in solver.muscles().iter().enumerate() {
            let cache = pc2::read(&out.join(format!("{}.pc2", muscle.name))).unwrap();
            assert_eq!((cache.start_frame, cache.sample_rate), (0.0, 1.0));
            assert_eq!(cache.samples.len(), 6);
            for (frame, sample) in cache.samples.iter().enumerate() {
                assert_eq!(sample, &expected[frame][m], "unit {unit} frame {frame}");
            }
        }
        let doc = glb_json(&out.join(GLB_FILE));
        let nodes = doc["nodes"].as_array().unwrap();
        assert_eq!(
            nodes.len(),
            solver.muscles().len() + solver.bones().len() + 1
        );
        assert_eq!(
            nodes[0]["extras"]["sinew_pc2"],
            format!("{}.pc2", solver.muscles()[0].name)
        );
        // The rest mesh is frame 0 in metres.
        let max = &doc["accessors"][0]["max"];
        let max_y = max[1].as_f64().unwrap() as f32;
        let first = expected[0][0].iter().map(|p| p.y).fold(f32::MIN, f32::max);
        assert_eq!(max_y, first);
        std::fs::remove_dir_all(&out).unwrap();
    }
}

fn surfaces_in_metres(solver: &sinew_core::Solver, unit: f32) -> Vec<Vec<glam::Vec3>> {
    solver
        .muscles()
        .iter()
        .map(|m| m.surface_positions().iter().map(|&p| p / unit).collect())
        .collect()
}

/// The JSON chunk and the binary chunk of a `.glb`.
fn glb_parts(path: &Path) -> (serde_json::Value, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    (
        serde_json::from_slice(&bytes[20..20 + len]).unwrap(),
        bytes[20 + len + 8..].to_vec(),
    )
}

/// Accessor `index` of a float `.glb` as flat `f32`s.
fn floats(doc: &serde_json::Value, bin: &[u8], index: usize) -> Vec<f32> {
    let accessor = &doc["accessors"][index];
    let view = &doc["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
    let start = view["byteOffset"].as_u64().unwrap() as usize;
    let len = view["byteLength"].as_u64().unwrap() as usize;
    bin[start..start + len]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// The skeleton is a node hierarchy keyed once per frame: composing a bone's
/// ancestors' keys at any frame gives the bone's pose in the solver then.
#[test]
fn the_skeleton_is_a_hierarchy_keyed_every_frame() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    let mut solver = scene.instantiate(path.parent().unwrap()).unwrap();
    let out = scratch("t5");
    let mut bake = Bake::start(&solver, &out, &[BakeFormat::Glb]).unwrap();
    let mut poses = vec![
        solver
            .bones()
            .iter()
            .map(|b| b.transform)
            .collect::<Vec<_>>(),
    ];
    for _ in 0..40 {
        solver.step();
        bake.record(&solver).unwrap();
        poses.push(solver.bones().iter().map(|b| b.transform).collect());
    }
    let files = bake.finish().unwrap();
    assert_eq!(files, [out.join(GLB_FILE)], "only the .glb was asked for");
    let (doc, bin) = glb_parts(&out.join(GLB_FILE));
    let nodes = doc["nodes"].as_array().unwrap();
    let bodies = solver.skeleton().unwrap().body_count();
    assert_eq!(
        nodes.len(),
        solver.muscles().len() + bodies + solver.bones().len() + 1
    );
    // Keys per node and path; every sampler has one key per frame, dt apart.
    let animation = &doc["animations"][0];
    let mut keys = std::collections::HashMap::new();
    for channel in animation["channels"].as_array().unwrap() {
        let sampler = &animation["samplers"][channel["sampler"].as_u64().unwrap() as usize];
        let input = floats(&doc, &bin, sampler["input"].as_u64().unwrap() as usize);
        assert_eq!(input.len(), 41);
        assert!((input[40] - 40.0 * scene.settings.dt).abs() < 1e-6);
        let node = channel["target"]["node"].as_u64().unwrap() as usize;
        let path = channel["target"]["path"].as_str().unwrap().to_string();
        keys.insert(
            (node, path),
            floats(&doc, &bin, sampler["output"].as_u64().unwrap() as usize),
        );
    }
    let parent: std::collections::HashMap<usize, usize> = nodes
        .iter()
        .enumerate()
        .flat_map(|(p, n)| {
            n["children"]
                .as_array()
                .into_iter()
                .flatten()
                .map(move |c| (c.as_u64().unwrap() as usize, p))
        })
        .collect();
    let vector = |node: usize, path: &str, frame: usize, width: usize| -> Vec<f32> {
        match keys.get(&(node, path.to_string())) {
            Some(k) => k[frame * width..(frame + 1) * width].to_vec(),
            None => nodes[node][path]
                .as_array()
                .map(|v| v.iter().map(|x| x.as_f64().unwrap() as f32).collect())
                .unwrap_or_else(|| {
                    if path == "scale" {
                        vec![1.0; 3]
                    } else if width == 4 {
                        vec![0.0, 0.0, 0.0, 1.0]
                    } else {
                        vec![0.0; 3]
                    }
                }),
        }
    };
    let world = |mut node: usize, frame: usize| {
        let mut pose = glam::Affine3A::IDENTITY;
        loop {
            let t = vector(node, "translation", frame, 3);
            let r = vector(node, "rotation", frame, 4);
            let s = vector(node, "scale", frame, 3);
            let local = glam::Affine3A::from_scale_rotation_translation(
                glam::Vec3::from_slice(&s),
                glam::Quat::from_slice(&r),
                glam::Vec3::from_slice(&t),
            );
            pose = local * pose;
            match parent.get(&node) {
                Some(&p) => node = p,
                None => return pose,
            }
        }
    };
    let first_bone = solver.muscles().len() + bodies;
    let mut moving = 0;
    for frame in [0, 20, 40] {
        for (b, expected) in poses[frame].iter().enumerate() {
            let got = world(first_bone + b, frame);
            let error = (got.matrix3 - expected.matrix3)
                .to_cols_array()
                .iter()
                .map(|x| x.abs())
                .fold(0.0, f32::max)
                .max((got.translation - expected.translation).length());
            assert!(
                error < 1e-5,
                "bone {b} frame {frame}: {got:?} vs {expected:?}"
            );
            moving += usize::from(frame > 0 && *expected != poses[0][b]);
        }
    }
    assert!(moving > 0, "T5's arm moves");
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn bad_folders_and_broken_caches_are_named() {
    let solver = builtin("P1").unwrap().instantiate(Path::new(".")).unwrap();
    // A folder under a regular file cannot be created (even by root).
    let file = scratch("file");
    std::fs::write(&file, b"not a folder").unwrap();
    let out = file.join("bake");
    match Bake::start(&solver, &out, &[BakeFormat::Pc2]) {
        Err(BakeError::Io { file, .. }) => assert_eq!(file, out),
        other => panic!("expected an I/O error naming {}: {other:?}", out.display()),
    }
    // A truncated cache.
    let dir = scratch("broken");
    let bake = Bake::start(&solver, &dir, &[BakeFormat::Pc2]).unwrap();
    let cache = bake.finish().unwrap().remove(0);
    let bytes = std::fs::read(&cache).unwrap();
    std::fs::write(&cache, &bytes[..bytes.len() - 4]).unwrap();
    let error = pc2::read(&cache).unwrap_err().to_string();
    assert!(
        error.contains(&cache.display().to_string()) && error.contains("size"),
        "{error}"
    );
    std::fs::write(&cache, b"POINTCACHE3").unwrap();
    let error = pc2::read(&cache).unwrap_err().to_string();
    assert!(error.contains("signature"), "{error}");
    // A sample of the wrong size.
    let mut writer = pc2::Pc2Writer::create(&dir.join("x.pc2"), 3, 0.0, 1.0).unwrap();
    let error = writer
        .write_sample(&[glam::Vec3::ZERO; 2])
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("x.pc2") && error.contains("2 points"),
        "{error}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn an_interrupted_bake_leaves_nothing_that_looks_complete_and_bakes_never_mix() {
    let mut solver = builtin("P1").unwrap().instantiate(Path::new(".")).unwrap();
    let out = scratch("interrupted");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "the user's own file").unwrap();
    // Interrupted after three frames: dropped without `finish`.
    let mut bake = Bake::start(&solver, &out, &[BakeFormat::Obj, BakeFormat::Pc2]).unwrap();
    for _ in 0..2 {
        solver.step();
        bake.record(&solver).unwrap();
    }
    drop(bake);
    let names = |dir: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    // Every OBJ frame is whole (written through a temporary file); the
    // cache is still `.partial`, so no reader takes it for a finished one.
    assert_eq!(
        names(&out),
        [
            "frame_0000.obj",
            "frame_0001.obj",
            "frame_0002.obj",
            "notes.txt",
            "oval.pc2.partial"
        ]
    );
    // A second bake into the folder is refused by name …
    let error = Bake::start(&solver, &out, &[BakeFormat::Pc2]).unwrap_err();
    match &error {
        BakeError::Existing { folder, count, .. } => {
            assert_eq!((folder, *count), (&out, 4), "{error}")
        }
        other => panic!("expected BakeError::Existing: {other}"),
    }
    assert!(error.to_string().contains("--replace"), "{error}");
    // … unless told to replace it: only the bake's files go.
    let bake = Bake::start_in(&solver, &out, &[BakeFormat::Pc2], ExistingFiles::Replace).unwrap();
    bake.finish().unwrap();
    assert_eq!(names(&out), ["notes.txt", "oval.pc2"]);
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn an_interrupted_bake_resumes_to_the_bytes_of_an_uninterrupted_one() {
    let formats = [BakeFormat::Obj, BakeFormat::Pc2];
    let bake_frames = |out: &Path, frames: u32, existing: ExistingFiles| {
        let mut solver = builtin("P3").unwrap().instantiate(Path::new(".")).unwrap();
        let mut bake = Bake::start_in(&solver, out, &formats, existing)?;
        for _ in 0..frames {
            solver.step();
            bake.record(&solver)?;
        }
        let resumed = bake.resumed();
        bake.finish().map(|files| (files, resumed))
    };
    let whole = scratch("resume_whole");
    let (files, _) = bake_frames(&whole, 6, ExistingFiles::Refuse).unwrap();
    // Interrupted after frame 3 (its caches left as `.partial`) …
    let resumed = scratch("resume_interrupted");
    {
        let mut solver = builtin("P3").unwrap().instantiate(Path::new(".")).unwrap();
        let mut bake = Bake::start(&solver, &resumed, &formats).unwrap();
        for _ in 0..3 {
            solver.step();
            bake.record(&solver).unwrap();
        }
    }
    // … and resumed: frames 0–3 checked and kept, the rest written.
    let (_, kept) = bake_frames(&resumed, 6, ExistingFiles::Resume).unwrap();
    assert_eq!(kept, 4);
    for file in &files {
        let name = file.file_name().unwrap();
        assert_eq!(
            std::fs::read(file).unwrap(),
            std::fs::read(resumed.join(name)).unwrap(),
            "{name:?}"
        );
    }
    assert!(!resumed.join("biceps.pc2.partial").exists());
    // Resuming another scene's bake is refused at its first frame.
    let mut other = builtin("P3").unwrap();
    other.muscles[0].params.activation = 0.5;
    let solver = other.instantiate(Path::new(".")).unwrap();
    let mut bake = Bake::start_in(&solver, &resumed, &formats, ExistingFiles::Resume);
    let error = match &mut bake {
        Err(e) => e.to_string(),
        Ok(_) => {
            let mut solver = solver;
            solver.step();
            bake.unwrap().record(&solver).unwrap_err().to_string()
        }
    };
    assert!(
        error.contains("frame_000") && error.contains("another bake"),
        "{error}"
    );
    std::fs::remove_dir_all(&whole).unwrap();
    std::fs::remove_dir_all(&resumed).unwrap();
}
