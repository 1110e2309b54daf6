// The translation unit that owns the test programs' precompiled header (tests/CMakeLists.txt,
// issue #51): a target of its own, so that every room's test program waits for the header alone,
// not for another test program's compile. Nothing else to compile here.
