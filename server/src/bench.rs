//! `mrstudy bench server`: drives the API from loopback with concurrent simulated participants.
