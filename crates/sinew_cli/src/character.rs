//! `import-makehuman`: the MakeHuman base mesh and rig → a skinned `.glb`.

use sinew_core::character::makehuman::{self, MakeHumanOptions};
use sinew_core::character::{SkinnedCharacter, glb};
use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// What the command line asks for besides the data folder.
#[derive(clap::Args)]
pub struct MakeHumanArgs {
    /// Rig of `rigs/standard/` (its `rig.<RIG>.json` and `weights.<RIG>.json`).
    #[arg(long, default_value = "game_engine")]
    pub rig: String,
    /// Output `.glb`.
    #[arg(long)]
    pub out: PathBuf,
}

/// Converts the MakeHuman data folder `dir` and writes the `.glb`.
pub fn run(dir: &Path, args: &MakeHumanArgs) -> Result<ExitCode, Box<dyn Error>> {
    let options = MakeHumanOptions {
        rig: args.rig.clone(),
        ..MakeHumanOptions::default()
    };
    let character = makehuman::import(dir, &options)?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
    }
    glb::write(&character, &args.out)?;
    println!("{}", summary(&character, &args.out));
    Ok(ExitCode::SUCCESS)
}

fn summary(character: &SkinnedCharacter, out: &Path) -> String {
    let (lo, hi) = character
        .positions
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let clips: Vec<String> = character
        .clips
        .iter()
        .map(|c| format!("{} ({:.1} s)", c.name, c.duration()))
        .collect();
    format!(
        "{}: {} skin vertices, {} triangles, {} joints, height {:.3} m, clips: {}",
        out.display(),
        character.positions.len(),
        character.triangles.len(),
        character.joints.len(),
        hi - lo,
        clips.join(", ")
    )
}
