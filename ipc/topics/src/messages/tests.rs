//! Layout is a contract between separately built processes: a change here must be deliberate
//! (bump the `/vN` in the type name with it).

use core::mem::{align_of, size_of};
use iceoryx2::prelude::ZeroCopySend;

use super::*;
use crate::CommandSource;

#[test]
fn sizes_and_alignment_are_pinned() {
    assert_eq!(size_of::<GroundTruth>(), 48);
    assert_eq!(size_of::<Observation>(), 8 * 3 + 96 * 4 + 8 + 8 + 8 + 48);
    assert_eq!(size_of::<Command>(), 8 * 4 + 8 + 8 + 8 + 8 + 8 + 8 * 8);
    assert_eq!(
        size_of::<ReplayChunk>(),
        8 * 3 + 8 + 20 * 96 * 4 + 20 * 2 * 4 + 24
    );
    assert_eq!(size_of::<WeightsHeader>(), 8 * 4 + 8 + 16 + 8);
    assert_eq!(size_of::<TrainerStatus>(), 8 * 5 + 8 + 8 * 3);
    assert_eq!(
        size_of::<ProcessStats>(),
        8 + 16 + 8 + 8 + 8 + 8 + 16 + 32 + 8 + 16 + 8
    );
    for a in [
        align_of::<Observation>(),
        align_of::<Command>(),
        align_of::<ReplayChunk>(),
        align_of::<WeightsHeader>(),
        align_of::<TrainerStatus>(),
        align_of::<ProcessStats>(),
    ] {
        assert_eq!(a, 8);
    }
}

#[test]
fn field_offsets_are_pinned() {
    assert_eq!(core::mem::offset_of!(Observation, image), 24);
    assert_eq!(core::mem::offset_of!(Observation, wheel_velocity), 24 + 384);
    assert_eq!(core::mem::offset_of!(Observation, command), 24 + 384 + 8);
    assert_eq!(core::mem::offset_of!(Observation, truth), 24 + 384 + 24);
    assert_eq!(core::mem::offset_of!(ReplayChunk, sources), 32 + 7680 + 160);
    assert_eq!(core::mem::offset_of!(Command, wheel_velocity), 32);
    assert_eq!(core::mem::offset_of!(Command, plan_first_step), 56);
    assert_eq!(core::mem::offset_of!(Command, plan), 72);
    assert_eq!(core::mem::offset_of!(ReplayChunk, images), 32);
}

#[test]
fn type_names_are_stable_and_distinct() {
    // SAFETY: type_name() is unsafe only because implementors must keep names unique.
    let names = unsafe {
        [
            Observation::type_name(),
            GroundTruth::type_name(),
            Command::type_name(),
            ReplayChunk::type_name(),
            WeightsHeader::type_name(),
            TrainerStatus::type_name(),
        ]
    };
    assert_eq!(
        names,
        [
            "mtanet::Observation/v2",
            "mtanet::GroundTruth/v1",
            "mtanet::Command/v3",
            "mtanet::ReplayChunk/v2",
            "mtanet::WeightsHeader/v3",
            "mtanet::TrainerStatus/v2",
        ]
    );
}

#[test]
fn a_command_gives_its_plan_for_the_steps_it_covers_only() {
    let mut c: Command = bytemuck::Zeroable::zeroed();
    assert_eq!(c.planned_at(0), None, "no plan");
    c.set_plan(100, 5, &[[1.0, 1.0], [2.0, 2.0]]);
    assert_eq!(c.planned_at(99), None);
    assert_eq!(c.planned_at(100), Some([1.0, 1.0]));
    assert_eq!(c.planned_at(104), Some([1.0, 1.0]));
    assert_eq!(c.planned_at(105), Some([2.0, 2.0]));
    assert_eq!(c.planned_at(109), Some([2.0, 2.0]));
    assert_eq!(c.planned_at(110), None, "run out");
    c.set_plan(0, 1, &[[3.0, 3.0]; 20]);
    assert_eq!(
        c.plan_len as usize, PLAN_SEGMENTS,
        "longer plans are cut to the wire's room"
    );
}

#[test]
fn command_source_round_trips() {
    for s in CommandSource::ALL {
        assert_eq!(CommandSource::from_u32(s as u32), Some(s));
    }
    assert_eq!(CommandSource::from_u32(7), None);
}
