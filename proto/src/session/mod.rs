//! Sans-IO session and frame-lock state machines (master side and node side), driven by `now` inputs.
