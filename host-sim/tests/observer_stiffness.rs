//! The drive's own stiffness identification (a lowering current step, its
//! ringing against the rig file's design at the payload the hold current
//! says): the compliance ratio it reads against the rig's true one, and
//! that payload and friction alone do not read as a stiffness change.

use host_sim::config::RigConfig;
use host_sim::rigs::Draw;
use host_sim::trainer::stiffness::{identify_compliance, RESOLUTION};

#[test]
fn the_lowering_step_reads_the_compliance_ratio_and_not_the_payload() {
    let design = RigConfig::nominal().unwrap();
    for (d, tol) in [
        (Draw { stiffness: 0.85, ..Draw::BASE }, 0.05),
        (Draw { stiffness: 1.15, ..Draw::BASE }, 0.05),
        (Draw { payload: 1.10, ..Draw::BASE }, RESOLUTION),
        (Draw { payload: 0.90, ..Draw::BASE }, RESOLUTION),
    ] {
        let id = identify_compliance(&d.apply(&design), &design, 31).unwrap();
        let truth = 1.0 / d.stiffness;
        assert!((id.measured_ratio / truth - 1.0).abs() <= tol, "{d:?}: {id:?}");
        // The payload the hold current says, within 2 % of the truth.
        assert!((id.payload_scale / d.payload - 1.0).abs() < 0.02, "{d:?}: {id:?}");
        if d.stiffness == 1.0 {
            assert_eq!(id.compliance_ratio, 1.0, "{id:?}");
        }
    }
}
