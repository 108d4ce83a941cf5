// Catch2 v3 or v2, whichever is installed.
#pragma once
#if __has_include(<catch2/catch_all.hpp>)
#include <catch2/catch_all.hpp>
using Catch::Approx;  // v2 has it at global scope
#else
#include <catch2/catch.hpp>
#endif
