//! The library's typed errors, checked in process: the variant and its values, not the words.

use kitti2pgm::convert::resume;
use kitti2pgm::format::layout::OutputDir;
use kitti2pgm::report::score::Predictions;
use kitti2pgm::Error;

use crate::util::*;

#[test]
fn a_second_conversion_into_a_locked_folder_is_refused() {
    let t = tmp();
    let out = t.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let _held = resume::lock(&OutputDir::new(&out)).unwrap();
    let plan = kitti2pgm::plan::Plan::build_as(
        &fixtures(),
        kitti2pgm::plan::FrameSelection::Annotated,
        None,
    )
    .unwrap();
    let opts = kitti2pgm::convert::ConvertOptions::new(&out);
    match kitti2pgm::convert::convert(&plan, &opts, &|_| {}) {
        Err(Error::Locked { path }) => assert_eq!(path, out),
        other => panic!("{other:?}"),
    }
    // Nothing was written beside the lock.
    let written: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(written.len(), 1, "{written:?}");
}

#[test]
fn two_predictions_of_one_frame_name_both_files() {
    let t = tmp();
    let pred = t.path().join("pred");
    let (a, b) = (pred.join("a"), pred.join("b"));
    for d in [&a, &b] {
        std::fs::create_dir_all(d).unwrap();
        std::fs::write(d.join("2011_09_26_0001_0000000000.npy"), b"").unwrap();
    }
    match Predictions::index(&pred) {
        Err(Error::DuplicatePrediction { path, frame, first }) => {
            assert_eq!(frame, "2011_09_26_0001_0000000000");
            let mut both = [path, first];
            both.sort();
            assert_eq!(
                both,
                [
                    a.join("2011_09_26_0001_0000000000.npy"),
                    b.join("2011_09_26_0001_0000000000.npy")
                ]
            );
        }
        other => panic!("{:?}", other.err()),
    }
}

#[test]
fn a_listed_frame_the_ground_truth_lacks_is_named() {
    use kitti2pgm::project::unproject::Method;
    use kitti2pgm::report::truth::GroundTruth;
    use kitti2pgm::report::unproject::{unproject_all, UnprojectOptions};
    let t = tmp();
    let out = t.path().join("out");
    convert_fixtures_in_process(&out);
    let gt = GroundTruth::open(&out).unwrap();
    let preds = Predictions::index(&out.join("lidar_2d")).unwrap();
    let missing: kitti2pgm::source::kitti::FrameId = "2011_09_26_0001_0000000007".parse().unwrap();
    let opts = UnprojectOptions {
        method: Method::Cell,
        raw: fixtures(),
        out: t.path().join("back"),
        only: Some([missing.clone()].into()),
        durability: Default::default(),
    };
    match unproject_all(&gt, &preds, &opts, &|_| {}) {
        Err(Error::FrameNotFound { path, frame }) => {
            assert_eq!(path, out);
            assert_eq!(frame, missing.to_string());
        }
        other => panic!("{other:?}"),
    }
}
