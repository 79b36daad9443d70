//! The PTU kind table against itself: every kind's driver, opened through the table, runs its
//! kind's mock (a separate implementation of the device side) over a real pseudo-terminal.

use std::time::Duration;

use sqscan_drivers::mock::{Faults, MockPort};
use sqscan_drivers::{Goal, PanTilt, PtuKind, PtuSettings};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_kind_drives_its_own_mock() {
    for kind in PtuKind::ALL {
        let port = MockPort::create(None).expect("a pty");
        let path = port.path().to_owned();
        let unit = kind.mock();
        let device = unit.device.clone();
        let task = tokio::spawn(port.serve(unit.device, Faults::default()));
        let mut ptu = kind
            .open(&path, &PtuSettings::default())
            .await
            .unwrap_or_else(|e| panic!("{kind}: the driver does not start on its mock: {e}"));
        assert_eq!(ptu.kind(), kind);
        let goal = Goal {
            pan_rad: 0.1,
            tilt_rad: 0.05,
            speed_rad_s: 0.5,
        };
        let end = ptu
            .move_and_track(goal, None, Duration::from_secs(30))
            .await
            .unwrap_or_else(|e| panic!("{kind}: move failed: {e}"));
        // Within a step of the coarsest unit (a PTU-D46 step is 0.9 mrad).
        assert!(
            (end.pan_rad - 0.1).abs() < 2e-3 && (end.tilt_rad - 0.05).abs() < 2e-3,
            "{kind}: {end:?}"
        );
        let (pan, tilt) = device.lock().unwrap().joint_angles(std::time::Instant::now());
        assert!(
            (pan - 0.1).abs() < 2e-3 && (tilt - 0.05).abs() < 2e-3,
            "{kind}: the mock is at {pan}, {tilt}"
        );
        task.abort();
    }
}
