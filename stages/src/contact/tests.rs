//! Reference and validation tests of the contact scenes (see each test's comment).
