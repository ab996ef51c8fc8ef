//! The names of the checks and of the severities: one spelling each, shared by the CLI, the
//! JSON and the docs.

use crate::source::kitti::DatasetKind;

/// How bad a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// Worth knowing; nothing is wrong.
    Note,
    /// Likely wrong.
    Warning,
    /// The data is wrong or unusable.
    Error,
}

crate::named_enum!(Severity, "severity", [
    Note => "note" [] "worth knowing; nothing is wrong",
    Warning => "warning" [] "likely wrong",
    Error => "error" [] "the data is wrong or unusable",
]);

macro_rules! checks {
    ($($variant:ident $name:literal $scans:literal $doc:literal;)*) => {
        /// A check: what it looks at is in `docs/check.md`.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum CheckName {
            $(#[doc = $doc] $variant,)*
        }

        crate::named_enum!(CheckName, "check", [$($variant => $name [] $doc,)*]);

        impl CheckName {
            /// Whether it needs the scans' points.
            pub fn needs_scans(self) -> bool {
                match self { $(CheckName::$variant => $scans,)* }
            }

            /// One line: what it finds.
            pub fn about(self) -> &'static str {
                match self { $(CheckName::$variant => $doc,)* }
            }
        }
    };
}

checks! {
    Read "read" false "A file that cannot be read or parsed (tracklets, calibration, labels).";
    Inventory "inventory" false "Scans, images, timestamps, poses and label files of each drive compared; stray and missing files.";
    Coverage "coverage" false "Annotated frames without a scan; scans past the last annotated frame.";
    LabelCount "label-count" false "A per-point label file whose count differs from its scan's points.";
    Calibration "calibration" false "Rotations orthonormal (det +1); rectified projections of the form [f 0 cx; 0 f cy; 0 0 1].";
    BeamModel "beam-model" true "Points whose elevation fits no beam of the sensor model (--sensor): a cloud not in the sensor's frame, or another sensor's.";
    CameraOverlap "camera-overlap" true "Share of the front points that land inside the camera image.";
    CameraAlignment "camera-alignment" true "Depth edges of projected points against image edges: does the calibrated position stand out?";
    BoxSize "box-size" false "Box sizes implausible for the object type.";
    PoseJump "pose-jump" false "A box that jumps between consecutive frames beyond a physical bound.";
    YawFlip "yaw-flip" false "A box heading that turns further between consecutive frames than a vehicle can.";
    BoxOverlap "box-overlap" false "Boxes of different objects that overlap at the same frame.";
    BoxGround "box-ground" true "A box whose bottom is far below or above the ground points around it.";
    EmptyBox "empty-box" true "A box with no point inside (a tracklet's: one marked fully visible, within range).";
    AnnotationEnds "annotation-ends" true "An annotation that ends while its object is still in the next scan.";
    AnnotationFalloff "annotation-falloff" false "Frames whose annotated-object count falls far below the drive's usual count.";
    LabelIds "label-ids" false "Per-point label ids unknown to the class map's yaml.";
    InstanceClasses "instance-classes" false "One instance id carrying several classes within a sequence.";
    ModelLabels "model-labels" false "Label files that are a model's output (infer --as-labels) not yet corrected, as its record says.";
    MovingStatic "moving-static" true "Points of a moving class that do not move between scans (needs poses.txt).";
    SplitBalance "split-balance" false "A class whose share in val differs from its share in train beyond a factor.";
    SplitLeak "split-leak" false "Frames of one drive in both train and val, or split lists naming absent frames.";
}

impl CheckName {
    /// Whether `--pictures` draws its findings: the box checks (a bird's-eye view) and the
    /// camera checks (the points over the image).
    pub fn pictured(self) -> bool {
        use CheckName::*;
        matches!(
            self,
            Calibration
                | CameraOverlap
                | CameraAlignment
                | BoxSize
                | PoseJump
                | YawFlip
                | BoxOverlap
                | BoxGround
                | EmptyBox
                | AnnotationEnds
        )
    }

    /// Whether it means anything for `layout`.
    pub fn applies_to(self, layout: DatasetKind) -> bool {
        use CheckName::*;
        match layout {
            DatasetKind::Raw => !matches!(
                self,
                LabelCount | LabelIds | InstanceClasses | ModelLabels | MovingStatic
            ),
            // The box checks of a sequence run on the boxes `kitti2pgm label` imported.
            DatasetKind::Sequence => !matches!(self, AnnotationFalloff),
            DatasetKind::Object => !matches!(
                self,
                PoseJump
                    | YawFlip
                    | AnnotationEnds
                    | AnnotationFalloff
                    | LabelCount
                    | LabelIds
                    | InstanceClasses
                    | ModelLabels
                    | MovingStatic
            ),
        }
    }
}
