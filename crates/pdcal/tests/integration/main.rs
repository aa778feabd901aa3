//! One test binary for the driver's integration tests: the `pdcal` binary run on files, as a user runs it: each module is one file of
//! tests, linked once instead of once per file.

mod absent_sensors;
mod bias_per_set;
mod bounded_inputs;
mod common;
mod consistency_verdict;
mod dark_offset;
mod files_contract;
mod hand_made_dataset;
mod import_command;
mod index_page;
mod input_checks;
mod joint_sets;
mod mag_align_photodiodes;
mod magcal_axes;
mod magcal_command;
mod magcal_reliability;
mod mounting_findings;
mod never_held;
mod onboard_commands;
mod output_faults;
mod output_replace;
mod pyramid_head_bias;
mod reliability_inputs;
mod repeatability;
mod sensor_axes;
mod skcube_honesty;
mod skcube_import;
mod smoothed_joint;
mod spikes;
mod streaming_outputs;
mod sun_line_half_turn;
mod sun_only_attitude;
mod time_used;
mod truth_is_not_read;
mod turned_head;
