//! Placeholder while the restructure moves the lidar experiments here.
