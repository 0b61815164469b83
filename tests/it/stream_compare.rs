//! `stream-compare` on a synthetic archive: one row per link and strategy, written as Markdown
//! and CSV, and the comparison says what it should — progressive tiles download less and
//! draw sooner over the slow link.

use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::Builtin;
use stripmask::sim::stream_compare::{CompareOptions, LINKS, StreamingCase, compare, write};

use crate::support::hills;

#[test]
fn every_link_and_strategy_gets_a_row_and_progressive_tiles_cost_fewer_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 33);
    let profile = DeviceProfile {
        width: 160,
        height: 120,
        ..DeviceProfile::pocketpc()
    };
    let options = CompareOptions {
        source: path.display().to_string(),
        flights: vec![Builtin::Diagonal],
        links: LINKS.to_vec(),
        seconds: Some(5.0),
        profile,
        out: dir.path().join("cmp"),
        progress: false,
    };
    let results = compare(&options).unwrap();
    assert_eq!(results.len(), LINKS.len() * StreamingCase::ALL.len());
    for link in &LINKS {
        let row = |s| {
            results
                .iter()
                .find(|r| r.link == link.name && r.strategy == s)
                .unwrap()
        };
        let (belts, progressive) = (row(StreamingCase::Belts), row(StreamingCase::Progressive));
        assert!(
            progressive.downloaded_bytes * 3 < belts.downloaded_bytes,
            "{}: {} vs {}",
            link.name,
            progressive.downloaded_bytes,
            belts.downloaded_bytes
        );
        assert!(belts.rendered_share.is_none() && progressive.rendered_share.is_some());
        assert!(progressive.holes.first_frame_s.is_some() && belts.holes.first_frame_s.is_some());
        assert!(
            row(StreamingCase::Progressive).hit_rate.is_none(),
            "no prediction, no hits"
        );
        for r in [belts, progressive, row(StreamingCase::Predicted)] {
            assert!(r.peak_memory_bytes <= options.profile.memory_limit_bytes());
            assert!(r.frames > 0 && r.mean_error_px.is_finite());
        }
    }
    let slow = |s| {
        results
            .iter()
            .find(|r| r.link == LINKS[0].name && r.strategy == s)
            .unwrap()
            .holes
            .first_frame_s
            .unwrap()
    };
    // Both draw the top first; whole tiles never come sooner than it.
    assert!(slow(StreamingCase::Progressive) <= slow(StreamingCase::Belts));
    let markdown = write(&options.out, &results, &options).unwrap();
    for s in StreamingCase::ALL {
        assert_eq!(markdown.matches(&format!("| {} |", s.name())).count(), 3);
    }
    let csv = std::fs::read_to_string(options.out.join("stream-compare.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + results.len());
    assert!(options.out.join("stream-compare.md").is_file());
}
