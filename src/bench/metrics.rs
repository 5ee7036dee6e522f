//! Error metrics of a visibility or image against its reference (being written).
