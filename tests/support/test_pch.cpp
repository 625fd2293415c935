// Holds the tests' precompiled headers (tests/CMakeLists.txt, sls_test_pch): nothing to run.
