// The translation unit that carries the tests' precompiled header (tests/CMakeLists.txt,
// fogmap_test_pch): every test binary reuses it.
