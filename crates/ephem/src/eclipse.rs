//! Eclipse by the Earth (in progress).
