//! One crack scene per test binary, built on first use.

use std::sync::OnceLock;

use stripmask::sim::crack_metric::CrackScene;

/// The crack scene, written to a temporary folder that lives as long as the test binary.
pub fn scene() -> &'static CrackScene {
    static SCENE: OnceLock<(tempfile::TempDir, CrackScene)> = OnceLock::new();
    &SCENE
        .get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let scene = CrackScene::build(dir.path()).unwrap();
            (dir, scene)
        })
        .1
}
