find_package(nlohmann_json 3 REQUIRED)
