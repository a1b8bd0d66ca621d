# Expected seconds of the longest tests (one thread each; clean-clone CI of 11a4ecc), read by ctest
# after the discovered tests. ctest -j starts the costliest tests first, but a clean clone has no
# Testing/Temporary/CTestCostData.txt, so without these it starts them in number order and the
# last long fold runs alone at the end. Names are matched without the
# ' # GetParam() = ...' that gtest_discover_tests appends; one that no longer exists is ignored.
set(_gd_costs
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/dress_fold" 470
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/long_sleeve_fold" 410
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/coat_fold" 350
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/tshirt_fold" 340
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/skirt_fold" 125
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/skirt_fling" 75
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/skirt_grasp" 70
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/pleat_skirt_fold" 65
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/pleat_skirt_fling" 60
  "SelfFold.NoIntersectionsThroughTwoFolds" 57
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/pleat_skirt_grasp" 41
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/dress_fling" 40
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/long_sleeve_fling" 39
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/cake_skirt_fold" 38)
foreach(_test IN LISTS gd_sim_tests_TESTS gd_validation_tests_TESTS gd_experiment_tests_TESTS)
  string(REGEX REPLACE "  # .*" "" _name "${_test}")
  list(FIND _gd_costs "${_name}" _at)
  if(_at GREATER_EQUAL 0)
    math(EXPR _at "${_at} + 1")
    list(GET _gd_costs ${_at} _cost)
    set_tests_properties("${_test}" PROPERTIES COST ${_cost})
  endif()
endforeach()
