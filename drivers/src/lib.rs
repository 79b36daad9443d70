//! Device drivers: filled by the drivers issue.
