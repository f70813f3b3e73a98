//! htfid-diagnose (under construction).
