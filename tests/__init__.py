"""The test suite: tests/<package>/ mirrors the package it tests (sim, conform, viz, garment);
tests/support/ holds the tools the tests share; fixtures are in tests/conftest.py."""
