# lmalign: the two set-up commands.
#   make demo   installs what is missing, builds in Release and aligns the real ground-truth pair.
#   make test   same set-up, then builds and runs every test.
# Real data: ../shared/data by default; set LMALIGN_DATA to point elsewhere.

BUILD_DIR ?= build
JOBS      ?= $(shell nproc 2>/dev/null || echo 2)
LMALIGN_DATA ?= $(abspath ../shared/data)
export LMALIGN_DATA

# Debian bookworm packages the project needs (build, tests, plots).
DEB_PACKAGES := cmake make g++ pkg-config libeigen3-dev libnanoflann-dev libcli11-dev \
                libyaml-cpp-dev nlohmann-json3-dev libfmt-dev libgtest-dev libgmock-dev \
                python3 python3-matplotlib python3-numpy

LMALIGN := $(BUILD_DIR)/apps/lmalign/lmalign
GT_PAIR := $(LMALIGN_DATA)/tum_fr1_desk/ground_truth_pair

.PHONY: all deps configure build test demo clean

all: build

# Install only the packages that are missing (needs root, as on a fresh Debian machine).
deps:
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "lmalign: installing missing Debian packages:$$missing"; \
	  if [ "$$(id -u)" -ne 0 ]; then echo "lmalign: run as root, or install them by hand:$$missing" >&2; exit 1; fi; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS)

demo: build
	@if [ ! -f "$(GT_PAIR)/desk_gt_a.txt" ]; then \
	  echo "lmalign demo: real data not found: looked for $(GT_PAIR)/desk_gt_a.txt" >&2; \
	  echo "  (set LMALIGN_DATA to the folder that holds tum_fr1_desk/)" >&2; exit 1; fi
	@echo "== lmalign demo: align desk_gt_a onto desk_gt_b (true transform: identity)"
	@echo "== source displaced by the paper's Table 1 pose: x=0 y=1 z=0.4 m, roll=10 pitch=0 yaw=22.5 deg"
	$(LMALIGN) align $(GT_PAIR)/desk_gt_a.txt $(GT_PAIR)/desk_gt_b.txt \
	  --weight all --k 5 --displace 0,1,0.4,10,0,22.5 --ground-truth identity \
	  --json $(BUILD_DIR)/demo/align.json

clean:
	rm -rf $(BUILD_DIR)
