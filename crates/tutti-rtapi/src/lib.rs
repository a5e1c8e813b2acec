//! RTAPI C library (see docs/rtapi.md).
