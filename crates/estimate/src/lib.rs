//! htfid-estimate (under construction).
