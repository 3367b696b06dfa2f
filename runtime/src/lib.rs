//! Placeholder: the wgpu runtime comes with its own issue.
