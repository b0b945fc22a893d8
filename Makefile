# bimanual_skills: the two commands.
#   make demo   install what is missing, build, and let the two simulated WAMs learn to fold a cloth from a faulty
#               demonstration (build/fold_demo)
#   make test   install what is missing, build, run every gtest and rostest; non-zero exit on any failure
# Also: make build, make bench (kinematics, dynamics/control, primitives, policy-update and vision benchmarks), make format, make deps,
#       make venv (build/venv: Ray and Gymnasium for the Python side).

SHELL := /bin/bash
# catkin needs Debian's python3 (with catkin_pkg), not a pyenv interpreter earlier on PATH.
export PATH := /usr/bin:/bin:$(PATH)
# The ROS graphs of the demo and the tests stay on this machine: a ROS 1 master has no authentication, so it
# listens on the loopback interface only unless ROS_IP or ROS_HOSTNAME says otherwise.
ifeq ($(strip $(ROS_IP)$(ROS_HOSTNAME)),)
export ROS_HOSTNAME := localhost
endif
COLCON_BUILD_FLAGS := --base-paths . --cmake-args -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release

.PHONY: deps venv build demo test bench format

deps:
	@bash scripts/install_deps.sh

# The Python side's packages from PyPI (Ray, Gymnasium; python/requirements.txt, pinned) in build/venv, which sees
# Debian's site packages: build/venv/bin/python runs the bindings, rospy and Ray (make test's Python tests use it).
VENV := $(CURDIR)/build/venv
venv: deps
	@bash scripts/make_venv.sh $(VENV)

build: deps venv
	colcon build $(COLCON_BUILD_FLAGS)

# The main job: two simulated WAMs learn to fold a cloth (config/fold_demo.yaml). A second run resumes from the
# rollouts already in build/fold_demo (delete it to start over).
FOLD_DEMO := $(CURDIR)/build/fold_demo
demo: build
	@echo "make demo: two simulated WAMs learn to fold a cloth better than they were shown: IDR-DMP_CMU with REPS from a"
	@echo "           faulty demonstration, 1 run x 15 updates x 12 rollouts on the Bullet simulation (config/fold_demo.yaml),"
	@echo "           results in $(FOLD_DEMO)"
	set -o pipefail; source install/setup.bash && bash scripts/fold_demo.sh $(CURDIR)/config/fold_demo.yaml \
	  $(FOLD_DEMO) 2>&1 | tee build/fold_demo.log
	/usr/bin/python3 scripts/plot_fold_learning.py $(FOLD_DEMO)
	@for f in summary.json epochs.csv rollouts.csv learning_curve.png coordination.png initial.png final.png \
	  filmstrip_initial.png filmstrip_final.png initial.gif final.gif best_rollout.bag; do \
	  if [ ! -s "$(FOLD_DEMO)/$$f" ]; then echo "make demo: FAILED: $(FOLD_DEMO)/$$f is missing (see build/fold_demo.log)"; exit 1; fi; done
	@if grep -q FATAL build/fold_demo.log; then echo "make demo: FAILED (see build/fold_demo.log)"; exit 1; fi
	@grep "fold quality .* →" build/fold_demo.log | sed 's/^fold_learner: /make demo: /'
	@echo "make demo: done. In $(FOLD_DEMO): learning_curve.png (the noise-free policy's fold quality, the rollouts' reward"
	@echo "           and q per epoch), filmstrip_initial.png and filmstrip_final.png, initial.gif and final.gif (the"
	@echo "           demonstration and the learned fold), coordination.png,"
	@echo "           summary.json, epochs.csv, rollouts.csv, table75.md, best_rollout.bag. Replay the best rollout in rviz:"
	@echo "             source install/setup.bash && roslaunch bimanual_skills fold.launch replay:=$(FOLD_DEMO)/best_rollout.bag"

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
