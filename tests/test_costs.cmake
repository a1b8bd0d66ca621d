# Expected seconds of the tests that take 4 s or more (one OpenMP thread each, ctest -j2 on this
# 2-core machine, 2026-11-30: the experiment label and the rest measured in two runs), read by
# ctest after the discovered tests. ctest -j starts the costliest tests first, but a clean clone has
# no Testing/Temporary/CTestCostData.txt: without these it starts them in number order, and a long
# test with a late number (the service's towel pick, the cake skirt's fold draws) runs on while the
# other core has nothing left. Names are
# matched without the ' # GetParam() = ...' that gtest_discover_tests appends; one that no longer
# exists is ignored. Refresh from a full run: the "Test #N: name ... Passed S sec" lines of ctest.
set(_gd_costs
  "DrapeReference.SimulatedCoefficientsOrderTheFabricsAsMeasured" 210
  "Drape.CoefficientConvergesWithTheMesh" 100
  "Folds/GarmentFold.LiesFoldedOnTheTable/tshirt_vertices_x2" 282
  "Folds/GarmentFold.LiesFoldedOnTheTable/hoodie_nominal" 186
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_vertices_x2" 152
  "Folds/GarmentFold.LiesFoldedOnTheTable/tshirt_nominal" 132
  "Folds/GarmentFold.LiesFoldedOnTheTable/coat_nominal" 125
  "Folds/GarmentFold.LiesFoldedOnTheTable/long_sleeve_nominal" 98
  "Folds/GarmentFold.LiesFoldedOnTheTable/dress_nominal" 85
  "Folds/GarmentFold.LiesFoldedOnTheTable/cake_skirt_inset_m5mm" 85
  "Folds/GarmentFold.LiesFoldedOnTheTable/cake_skirt_inset_p5mm" 76
  "Folds/GarmentFold.LiesFoldedOnTheTable/cake_skirt_speed_m5pct" 68
  "Folds/GarmentFold.LiesFoldedOnTheTable/cake_skirt_nominal" 68
  "Folds/GarmentFold.LiesFoldedOnTheTable/cake_skirt_speed_p5pct" 64
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_inset_p5mm" 56
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_inset_m5mm" 55
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_speed_m5pct" 48
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_nominal" 46
  "Folds/GarmentFold.LiesFoldedOnTheTable/pleat_skirt_speed_p5pct" 46
  "Backends/GpuPaths.PinnedSheetSwingingMatchesTheCpuPaths/CpuGpuPaths" 38
  "RobotScenesRpc.FingersPickATowelOffTheTableThroughTheService" 38
  "PinchStroke.AStepTheLineSearchCutShortDoesNotEndNewton" 38
  "PinchStroke.AHandAtTheEndOfItsStepNeverStallsNewton" 22
  "PinchStroke.SurfaceSamplesHoldTheStripInEveryDraw" 22
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_vertices_x2" 31
  "Backends/GpuPaths.CollidersWithFrictionMatchTheCpuPaths/CpuGpuPaths" 29
  "RobotArms.FingersPickClothOffTheTable" 26
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/long_sleeve_fling" 20
  "TableCut.AFoldedSheetLandsInFewerNewtonIterations" 18
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/long_sleeve_grasp" 15
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/hoodie_fling" 14
  "PinchedLayers.StayApartWithoutTheFailSafeWhileThePadsCarryThemUp" 13
  "DeterministicGpuPaths.MatchTheCpuBackendToRounding" 13
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_nominal" 13
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/tshirt_grasp" 13
  "YieldingCollider.APadClosingFasterThanTheStackCanMoveStopsShort" 13
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/skirt_fling" 13
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_speed_p5pct" 13
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/tshirt_fling" 13
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_inset_p5mm" 13
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_vertices_x2" 13
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/dress_fling" 13
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_speed_m5pct" 12
  "Folds/GarmentFold.LiesFoldedOnTheTable/skirt_inset_m5mm" 12
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/skirt_grasp" 12
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/pleat_skirt_fling" 11
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"nylon\"" 11
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/coat_fling" 11
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/dress_grasp" 10
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/hoodie_grasp" 10
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/pleat_skirt_grasp" 10
  "SelfFold.NoIntersectionsThroughTwoFolds" 9
  "CliTest.RunAsAJobWritesTheReportFiles" 9
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/coat_grasp" 8
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"wool\"" 8
  "CliTest.RobotModeRunsLocallyAndAsAJobAndIsRefusedWithoutAUrdf" 8
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"fur\"" 7
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/cake_skirt_fling" 7
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"silk\"" 7
  "SyntheticCapture.IcpRepairsAMiscalibratedCamera" 7
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_nominal" 7
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_speed_p5pct" 6
  "RobotArms.FingersHoldAStripByFrictionAndLiftIt" 6
  "CliTest.ViewWritesAScreenshotOfTheScenesPage" 6
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_speed_m5pct" 6
  "Convergence.JobsRunTheRunsAtOnceWithTheResultsOfOneAfterAnother" 6
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_inset_p5mm" 6
  "Folds/GarmentFold.LiesFoldedOnTheTable/towel_inset_m5mm" 6
  "AllTypes/GarmentTask.SurvivesWithItsPhysicalOutcome/cake_skirt_grasp" 6
  "ServerRpc.AssetsInfoAndAnUploadedMeshThatSurvivesARestart" 6
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"linen\"" 5
  "CantileverMesh.TwoResolutionsAgreeWithinOneAndAHalfPercent" 5
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"velvet\"" 5
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"cotton\"" 5
  "TenFabrics/Cantilever.BendingLengthMatchesRigidity/\"knit\"" 5
  "YieldingCollider.PadsCarryingAPinchSidewaysTakeTheStackAlongWithoutCrossings" 5
  "ScenesRpc.ASlowSubscriberLosesTheOldestFramesAndIsToldHowMany" 4)

get_cmake_property(_gd_vars VARIABLES)
foreach(_list IN LISTS _gd_vars)
  if(NOT _list MATCHES "^gd_discovered_[0-9]+_TESTS$")
    continue()
  endif()
  foreach(_test IN LISTS ${_list})
    string(REGEX REPLACE "  # .*" "" _name "${_test}")
    list(FIND _gd_costs "${_name}" _at)
    if(_at GREATER_EQUAL 0)
      math(EXPR _at "${_at} + 1")
      list(GET _gd_costs ${_at} _cost)
      set_tests_properties("${_test}" PROPERTIES COST ${_cost})
    endif()
  endforeach()
endforeach()
