//! Placeholder while the restructure moves the slamot experiments here.
