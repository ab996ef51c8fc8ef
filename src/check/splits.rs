//! Splits and balance: class shares of train against val, and drives split across both.

use std::collections::{BTreeMap, BTreeSet};

use super::read::DriveRead;
use super::{CheckName as C, CheckOptions, Collector, Severity as S};
use crate::format::imageset;
use crate::plan::split::{assign, SplitRule};
use crate::source::kitti::FrameId;

/// Per class counts (object poses, or labelled points) of each annotated frame of a drive.
#[derive(Debug, Default)]
pub(crate) struct DriveAnnotations {
    pub frames: Vec<(FrameId, BTreeMap<String, u64>)>,
}

impl DriveAnnotations {
    /// Boxes per object type (raw, object set), or `labelled`: the points per class that the
    /// label check counted (sequences).
    pub(crate) fn of(
        r: &DriveRead,
        labelled: Vec<(u32, BTreeMap<String, u64>)>,
    ) -> DriveAnnotations {
        let d = &r.drive;
        let mut frames = Vec::new();
        if let Some(t) = r.tracklets() {
            for f in 0..t.end_frame() {
                let mut m = BTreeMap::new();
                for (_, tr, _) in t.at(f) {
                    *m.entry(tr.object_type.as_str().to_string()).or_default() += 1;
                }
                if !m.is_empty() {
                    frames.push((d.frame_id(f), m));
                }
            }
        }
        for (f, (objects, _)) in r.objects() {
            let mut m = BTreeMap::new();
            for o in objects.iter().filter(|o| o.kind != "DontCare") {
                *m.entry(o.kind.clone()).or_default() += 1;
            }
            frames.push((d.frame_id(*f), m));
        }
        frames.extend(labelled.into_iter().map(|(f, m)| (d.frame_id(f), m)));
        DriveAnnotations { frames }
    }
}

/// The val frames: the ImageSet lists' when given (with their leak checks), else the layout's
/// default rule's.
fn val_frames(
    all: &[FrameId],
    opts: &CheckOptions,
    c: &mut Collector,
) -> Option<BTreeSet<FrameId>> {
    let Some(dir) = &opts.imageset else {
        let dataset = all.first()?.dataset;
        return assign(&SplitRule::default_for(dataset), all).ok();
    };
    let read = |name: &str, c: &mut Collector| -> Option<Vec<FrameId>> {
        let path = dir.join(name);
        match imageset::read(&path) {
            Ok(v) => Some(v),
            Err(e) => {
                c.add(C::Read, S::Error, &path, None, None, e.to_string());
                None
            }
        }
    };
    let (train, val) = (read("train.txt", c)?, read("val.txt", c)?);
    let known: BTreeSet<&FrameId> = all.iter().collect();
    for (name, list) in [("train.txt", &train), ("val.txt", &val)] {
        let absent: Vec<&FrameId> = list.iter().filter(|id| !known.contains(id)).collect();
        if let Some(first) = absent.first() {
            c.add(
                C::SplitLeak,
                S::Warning,
                &dir.join(name),
                Some(first.frame),
                None,
                format!(
                    "{} listed frames have no annotation here (first {first})",
                    absent.len()
                ),
            );
        }
    }
    let by_drive = |l: &[FrameId]| -> BTreeMap<String, usize> {
        let mut m = BTreeMap::new();
        for id in l
            .iter()
            .filter(|id| id.dataset != crate::source::kitti::DatasetKind::Object)
        {
            *m.entry(id.drive_name()).or_default() += 1;
        }
        m
    };
    let (tr, va) = (by_drive(&train), by_drive(&val));
    for (drive, n) in &tr {
        if let Some(m) = va.get(drive) {
            c.add(C::SplitLeak, S::Warning, &dir.join("val.txt"), None, None,
                format!("drive {drive} has {n} frames in train and {m} in val: neighbouring frames are near copies, so val scores are inflated"));
        }
    }
    Some(val.into_iter().collect())
}

/// Compares the class shares of train and val.
pub(crate) fn check(drives: &[DriveAnnotations], opts: &CheckOptions, c: &mut Collector) {
    let all: Vec<FrameId> = drives
        .iter()
        .flat_map(|d| d.frames.iter().map(|(id, _)| id.clone()))
        .collect();
    let Some(val) = val_frames(&all, opts, c) else {
        return;
    };
    let mut sums: [BTreeMap<String, u64>; 2] = Default::default();
    for (id, m) in drives.iter().flat_map(|d| &d.frames) {
        let side = &mut sums[val.contains(id) as usize];
        for (k, n) in m {
            *side.entry(k.clone()).or_default() += n;
        }
    }
    let totals = [sums[0].values().sum::<u64>(), sums[1].values().sum::<u64>()];
    let file = opts
        .imageset
        .clone()
        .unwrap_or_else(|| std::path::PathBuf::from("(default split)"));
    if totals
        .iter()
        .any(|&n| (n as f64) < c.t().balance_min_count.max(1.0))
    {
        c.add(
            C::SplitBalance,
            S::Note,
            &file,
            None,
            None,
            format!(
                "not judged: {} annotations in train, {} in val",
                totals[0], totals[1]
            ),
        );
        return;
    }
    let factor = c.t().balance_factor.max(1.0);
    let classes: BTreeSet<&String> = sums[0].keys().chain(sums[1].keys()).collect();
    for k in classes {
        let share = |i: usize| sums[i].get(k).copied().unwrap_or(0) as f64 / totals[i] as f64;
        let (t, v) = (share(0), share(1));
        // Rare classes (under 0.5% of both) drift by chance; leave them alone.
        if t.max(v) < 0.005 {
            continue;
        }
        let ratio = if t == 0.0 { f64::INFINITY } else { v / t };
        if ratio > factor || ratio < 1.0 / factor {
            c.add(C::SplitBalance, S::Warning, &file, None, None,
                format!("{k}: {:.2}% of train's annotations, {:.2}% of val's (a factor {:.1}, above {factor}): val scores this class on a different mix",
                    t * 100.0, v * 100.0, if ratio >= 1.0 { ratio } else { 1.0 / ratio }));
        }
    }
}
