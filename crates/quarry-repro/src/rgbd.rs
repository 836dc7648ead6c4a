//! Placeholder while the restructure moves the rgbd experiments here.
