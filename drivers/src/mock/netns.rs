//! Tests of networked devices and middleware (GigE Vision, DDS) run inside a private network
//! namespace that has only loopback.

/// For a test of a networked device or middleware: whether to run the test's body in this
/// process. Inside a private network namespace (the environment says so) it is true. Outside,
/// the test binary runs this one test (`test`, its full name) again inside a new namespace with
/// only loopback up, multicast on (`unshare -n`, root), so that no discovery broadcast, DDS
/// multicast or stream packet can leave the machine, fails if it failed there, and returns
/// false; where no namespace can be had it prints `SKIPPED` and returns false, or fails where
/// `SQSCAN_REQUIRE_NETNS` is set (as the README's test command sets it, so that CI cannot pass
/// without these tests).
pub fn in_private_network(test: &str) -> bool {
    const INSIDE: &str = "SQSCAN_IN_PRIVATE_NETWORK";
    if std::env::var_os(INSIDE).is_some() {
        return true;
    }
    let skip = |why: &str| {
        assert!(
            std::env::var_os("SQSCAN_REQUIRE_NETNS").is_none(),
            "{test}: no private network namespace, and SQSCAN_REQUIRE_NETNS is set: {why}"
        );
        eprintln!("SKIPPED {test}: no private network namespace here (unshare -n needs root): {why}");
    };
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => panic!("{test}: cannot find the test binary: {e}"),
    };
    let out = std::process::Command::new("unshare")
        .args([
            "-n",
            "sh",
            "-c",
            "ip link set lo up && ip link set lo multicast on && exec \"$0\" \"$@\"",
        ])
        .arg(&exe)
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(INSIDE, "1")
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            assert!(
                text.contains("1 passed"),
                "{test} did not run in the namespace:\n{text}"
            );
        }
        Ok(o) => {
            let err = String::from_utf8_lossy(&o.stderr);
            if err.contains("unshare failed") || err.contains("Operation not permitted") {
                skip(&err);
            } else {
                panic!(
                    "{test} failed in its private network namespace:\n{}\n{err}",
                    String::from_utf8_lossy(&o.stdout)
                );
            }
        }
        Err(e) => skip(&format!("cannot run unshare: {e}")),
    }
    false
}
