//! The interactive walkthrough window (`mirage view`). Being written; see issue 7.

use clap::Args;

/// Flags of `mirage view`.
#[derive(Args, Clone, Debug)]
pub struct ViewArgs {
    /// Scene file or built-in scene name (default: the built-in Cornell box).
    pub scene: Option<String>,
}

/// Runs the viewer.
pub fn run(args: &ViewArgs) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    Err(format!("mirage view {}: the viewer is not built yet", args.scene.as_deref().unwrap_or("")).into())
}
