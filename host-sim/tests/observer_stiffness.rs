//! The drive's own stiffness identification (a current step from the hold
//! current, its ringing against the rig file's design at the payload the
//! hold current says), run by the host tool's code on simulated drives
//! over the protocol: the compliance ratio it reads against the rig's true
//! one, and that payload alone does not read as a stiffness change.

use host_sim::config::RigConfig;
use host_sim::rigs::Draw;
use host_sim::trainer::stiffness::{identify_compliance, RESOLUTION};

#[test]
fn the_probe_reads_the_compliance_ratio_and_not_the_payload() {
    let design = RigConfig::nominal().unwrap();
    for (d, tol) in [
        (Draw { stiffness: 0.85, ..Draw::BASE }, 0.05),
        (Draw { stiffness: 1.15, ..Draw::BASE }, 0.05),
        (Draw { payload: 1.10, ..Draw::BASE }, RESOLUTION),
        (Draw { payload: 0.90, ..Draw::BASE }, RESOLUTION),
    ] {
        let id = identify_compliance(&d.apply(&design), &design, 31).unwrap();
        eprintln!("{d:?}: {id:?}");
        let truth = 1.0 / d.stiffness;
        assert!((id.measured_ratio / truth - 1.0).abs() <= tol, "{d:?}: {id:?}");
        // The stated uncertainty covers the error (2 σ, about 95 %).
        assert!((id.measured_ratio - truth).abs() <= 2.0 * id.ratio_uncertainty, "{d:?}: {id:?}");
        // The payload the hold current says, within 2 % of the truth.
        assert!((id.payload_scale / d.payload - 1.0).abs() < 0.02, "{d:?}: {id:?}");
        if d.stiffness == 1.0 {
            assert_eq!(id.compliance_ratio, 1.0, "{id:?}");
        }
    }
}
