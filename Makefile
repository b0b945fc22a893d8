# bimanual_skills: the two commands.
#   make demo   install what is missing, build, run the most complete end-to-end job
#   make test   install what is missing, build, run every gtest and rostest; non-zero exit on any failure
# Also: make build, make bench (kinematics, dynamics/control, primitives, policy-update and vision benchmarks), make format, make deps.

SHELL := /bin/bash
# catkin needs Debian's python3 (with catkin_pkg), not a pyenv interpreter earlier on PATH.
export PATH := /usr/bin:/bin:$(PATH)
COLCON_BUILD_FLAGS := --base-paths . --cmake-args -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release

.PHONY: deps build demo test bench format

deps:
	@bash scripts/install_deps.sh

build: deps
	colcon build $(COLCON_BUILD_FLAGS)

demo: build
	@echo "make demo: bimanual WAM model, robot_state_publisher and ik_server; a two-handed grasp solved through the"
	@echo "           IK service, commanded, and checked against the published tf (the cloth-folding demo replaces"
	@echo "           this when it exists)"
	set -o pipefail; source install/setup.bash && roslaunch bimanual_skills demo.launch 2>&1 | tee build/demo.log
	@if grep -q -E 'NOT REACHED|not available|failed|FATAL' build/demo.log || ! grep -q 'target reached' build/demo.log; then \
	  echo "make demo: FAILED (see above)"; exit 1; fi
	@echo "make demo: done; both arms reached their IK targets"

test: build
	@bash scripts/run_tests.sh

bench: build
	./build/bimanual_skills/devel/lib/bimanual_skills/kinematics_bench --benchmark_repetitions=5 \
	  --benchmark_report_aggregates_only=true --benchmark_out=build/kinematics_bench.json --benchmark_out_format=json
	./build/bimanual_skills/devel/lib/bimanual_skills/control_bench --realtime --benchmark_repetitions=5 \
	  --benchmark_report_aggregates_only=true --benchmark_out=build/control_bench.json --benchmark_out_format=json
	./build/bimanual_skills/devel/lib/bimanual_skills/primitives_bench --benchmark_repetitions=5 \
	  --benchmark_report_aggregates_only=true --benchmark_out=build/primitives_bench.json --benchmark_out_format=json
	./build/bimanual_skills/devel/lib/bimanual_skills/learning_bench --benchmark_repetitions=5 \
	  --benchmark_report_aggregates_only=true --benchmark_out=build/learning_bench.json --benchmark_out_format=json
	./build/bimanual_skills/devel/lib/bimanual_skills/vision_bench --benchmark_repetitions=5 \
	  --benchmark_report_aggregates_only=true --benchmark_out=build/vision_bench.json --benchmark_out_format=json

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')
