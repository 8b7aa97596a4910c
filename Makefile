# meshstream build. `make` builds everything (release), `make test` builds with
# AddressSanitizer + UndefinedBehaviorSanitizer and runs every test, `make check`
# only the unit tests (in parallel, a few minutes), `make bench`
# runs the benchmarks, `make demo` sets up and runs the demo, `make fuzz` builds the
# libFuzzer targets (clang), `make clean` removes build/.
#
# Layout (docs/ARCHITECTURE.md): the code lives in rooms, folders named for what
# they hold (common/codec, server/bake, client/view, ...). Every *.c of a room goes
# into that room's static library, except files named *_main.c, each of which is a
# program (server/bake/meshbake_main.c -> meshbake). A room's files see only the
# headers of the rooms it USES (and what those use, transitively): including a
# header from any other room fails to compile. tests/test_*.c are cmocka test
# programs and see every room; tests/fuzz/fuzz_*.c are fuzz targets.

CC      ?= gcc
CXX     ?= g++
MODE    ?= release
BUILD   := build/$(MODE)

# A build folder made before the rooms (or by an older layout) holds objects and
# dependency files under old paths that make would trust: start it afresh.
LAYOUT  := rooms-1
ifneq ($(shell cat $(BUILD)/.layout 2>/dev/null),$(LAYOUT))
  $(shell rm -rf $(BUILD) && mkdir -p $(BUILD) && echo $(LAYOUT) > $(BUILD)/.layout)
endif

WARN    := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wvla
CSTD    := -std=c11 -D_DEFAULT_SOURCE -D_FILE_OFFSET_BITS=64
ifeq ($(MODE),asan)
  OPT   := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
else
  OPT   := -O2 -g -DNDEBUG
endif
CFLAGS   := $(CSTD) $(WARN) $(OPT) -pthread $(EXTRA_CFLAGS)
CXXFLAGS := -std=c++17 -Wall -Wextra -Werror $(OPT) -pthread $(EXTRA_CFLAGS)
LDFLAGS  := $(OPT) -pthread

# Rooms, lowest first (link order is the reverse). USES_room lists the rooms a
# room may include directly; PKGS_room the Debian libraries its own code calls
# (pkg-config names; Embree 3 ships no .pc file and is named embree3).
ROOMS := common/util common/mesh common/codec common/apo common/camera \
         common/archive protocol server/geometry server/apo server/bake \
         server/serve server/study client/core client/load client/view
USES_common/util     :=
USES_common/mesh     := common/util
USES_common/codec    := common/mesh
USES_common/apo      := common/util
USES_common/camera   := common/util
USES_common/archive  := common/codec common/camera
USES_protocol        := common/util
USES_server/geometry := common/mesh
USES_server/apo      := server/geometry common/apo common/archive
USES_server/bake     := server/apo
USES_server/serve    := common/archive protocol
USES_server/study    := common/apo common/archive
USES_client/core     := common/archive protocol
USES_client/load     := client/core
USES_client/view     := client/core common/apo
PKGS_common/util     := jansson libpng zlib
PKGS_common/codec    := zlib
PKGS_common/apo      := zlib
PKGS_common/archive  := jansson zlib
PKGS_protocol        := zlib
PKGS_server/geometry := openmesh
PKGS_server/apo      := embree3
PKGS_server/bake     := jansson zlib
PKGS_server/serve    := libevent jansson zlib
PKGS_server/study    := embree3 jansson
PKGS_client/core     := libevent zlib
PKGS_client/load     := libevent jansson
PKGS_client/view     := glfw3 epoxy libevent jansson zlib

# room_closure: the room and every room it uses, transitively.
room_closure = $(sort $(1) $(foreach u,$(USES_$(1)),$(call room_closure,$(u))))
reverse      = $(if $(1),$(call reverse,$(wordlist 2,$(words $(1)),$(1))) $(firstword $(1)))
room_lib     = $(BUILD)/lib/libms_$(subst /,_,$(1)).a
# The libraries a program of room $(1) links, highest room first.
room_libs    = $(foreach r,$(call reverse,$(ROOMS)),$(if $(filter $(r),$(call room_closure,$(1))),$(call room_lib,$(r))))
room_pkgs    = $(sort $(foreach r,$(call room_closure,$(1)),$(PKGS_$(r))))
pkg_libs     = $(if $(filter embree3,$(1)),-lembree3) \
               $(if $(filter-out embree3,$(1)),$(shell pkg-config --libs $(filter-out embree3,$(1))))
pkg_cflags   = $(if $(filter-out embree3,$(1)),$(shell pkg-config --cflags $(filter-out embree3,$(1))))

lib_srcs  = $(filter-out %_main.c,$(wildcard $(1)/*.c))
lib_objs  = $(patsubst %.c,$(BUILD)/%.o,$(call lib_srcs,$(1))) $(patsubst %.cpp,$(BUILD)/%.o,$(wildcard $(1)/*.cpp))
MAINS     := $(wildcard $(addsuffix /*_main.c,$(ROOMS)))
PROGRAMS  := $(patsubst %_main.c,$(BUILD)/bin/%,$(notdir $(MAINS)))
TEST_SRCS := $(wildcard tests/test_*.c)
TESTS     := $(patsubst tests/%.c,$(BUILD)/tests/%,$(TEST_SRCS))
TESTSUPPORT := $(patsubst %.c,$(BUILD)/%.o,$(wildcard tests/support/*.c))
ALL_LIBS  := $(foreach r,$(call reverse,$(ROOMS)),$(call room_lib,$(r)))
ALL_PKGS  := $(sort $(foreach r,$(ROOMS),$(PKGS_$(r))))
LINK      := $(CXX)

.PHONY: all test check bench demo fuzz clean programs tests deps screenshots rooms room-flags study
.SECONDARY:
all: programs

programs: $(PROGRAMS)
tests: $(TESTS) $(PROGRAMS)

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(ROOM_CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/%.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) $(ROOM_CFLAGS) -MMD -MP -c $< -o $@

# Per room: what its sources see, its library, and its programs (one link rule).
define room_rules
$(BUILD)/$(1)/%.o: ROOM_CFLAGS := $(addprefix -I,$(call room_closure,$(1))) $(call pkg_cflags,$(call room_pkgs,$(1)))
$(call room_lib,$(1)): $(call lib_objs,$(1)) | $(BUILD)/empty.o
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^ $$(if $$^,,$(BUILD)/empty.o)
$(foreach m,$(wildcard $(1)/*_main.c),$(BUILD)/bin/$(notdir $(m:_main.c=)): $(BUILD)/$(m:.c=.o) $(call room_libs,$(1))
	@mkdir -p $$(dir $$@)
	$$(LINK) $$(LDFLAGS) $$< $(call room_libs,$(1)) $(call pkg_libs,$(call room_pkgs,$(1))) -lm -o $$@
)
endef
$(foreach r,$(ROOMS),$(eval $(call room_rules,$(r))))

# Tests see every room.
$(BUILD)/tests/%.o: ROOM_CFLAGS := $(addprefix -I,$(ROOMS) tests/support) $(call pkg_cflags,$(ALL_PKGS))

# The viewer's GLSL (client/view/shaders/*.glsl) is embedded into libmsview as C
# strings (declared in client/view/ms_render_shaders.h) by a generated source.
SHADER_SRCS := $(wildcard client/view/shaders/*.glsl)
SHADER_GEN  := $(BUILD)/gen/ms_render_shaders.c
$(SHADER_GEN): $(SHADER_SRCS) client/view/shaders/embed_shaders.py
	@mkdir -p $(dir $@)
	python3 client/view/shaders/embed_shaders.py $@ $(SHADER_SRCS)
$(BUILD)/gen/ms_render_shaders.o: $(SHADER_GEN)
	$(CC) $(CFLAGS) -Iclient/view -MMD -MP -c $< -o $@
$(call room_lib,client/view): $(BUILD)/gen/ms_render_shaders.o

# An empty archive still needs one member for ar on some systems.
$(BUILD)/empty.o:
	@mkdir -p $(dir $@)
	echo 'typedef int ms_empty_translation_unit;' | $(CC) $(CFLAGS) -x c -c - -o $@

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(TESTSUPPORT) $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(TESTSUPPORT) $(ALL_LIBS) $(call pkg_libs,$(ALL_PKGS) cmocka) -lm -o $@

# The whole suite under ASan + UBSan, tier by tier (tests/tiers.txt), each tier
# timed. Tests run from the repository root and find the shared models through
# MESHSTREAM_MODELS (default ../shared/data/models).
test:
	@$(MAKE) --no-print-directory MODE=asan tests
	@MODE=asan scripts/run-tests

# The unit tier alone, every core at once: no servers, no display, no shared models.
UNIT_TESTS := $(patsubst %,build/asan/tests/%,$(shell awk '$$1 ~ /^test_/ && $$2 == "unit" {print $$1}' tests/tiers.txt))
check:
	@$(MAKE) --no-print-directory MODE=asan $(UNIT_TESTS)
	@MODE=asan TIERS=unit scripts/run-tests

bench: programs
	@scripts/bench

# What accuracy costs: sweeps over the dragon and the demo model, docs/ACCURACY.md
# and docs/images/study-*.png (scripts/study; 10 to 15 minutes; not in CI).
study: programs
	@scripts/study

# The viewer's pictures in docs/images/ (headless meshview; Xvfb when no DISPLAY).
screenshots: programs
	@scripts/screenshots

demo:
	@scripts/install-deps
	@$(MAKE) --no-print-directory programs
	@scripts/demo

fuzz:
	@$(MAKE) --no-print-directory -f tests/fuzz/fuzz.mk

deps:
	@scripts/install-deps

clean:
	rm -rf build

# The layering, for tests/test_layering.c and for reading: `make -s rooms`, and
# `make -s room-flags ROOM=client/view` (the include paths that room compiles with).
rooms:
	@echo $(ROOMS)
room-flags:
	@echo $(addprefix -I,$(call room_closure,$(ROOM)))

-include $(shell find build -name '*.d' 2>/dev/null)
