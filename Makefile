# meshstream build. `make` builds everything (release), `make test` builds with
# AddressSanitizer + UndefinedBehaviorSanitizer and runs every test, `make bench`
# runs the benchmarks, `make demo` sets up and runs the demo, `make fuzz` builds the
# libFuzzer targets (clang), `make clean` removes build/.
#
# Layout convention: every *.c in a role folder (common, protocol, server, client)
# goes into that folder's static library, except files named *_main.c, each of which
# is a program linked against the libraries (server/meshbake_main.c -> meshbake).
# tests/test_*.c are cmocka test programs; tests/fuzz/fuzz_*.c are fuzz targets.

CC      ?= gcc
CXX     ?= g++
MODE    ?= release
BUILD   := build/$(MODE)

WARN    := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wvla
CSTD    := -std=c11 -D_DEFAULT_SOURCE -D_FILE_OFFSET_BITS=64
ifeq ($(MODE),asan)
  OPT   := -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
else
  OPT   := -O2 -g -DNDEBUG
endif
CFLAGS   := $(CSTD) $(WARN) $(OPT) -Icommon -Iprotocol -Iserver -Iclient -Iclient/view -Iserver/study -Itests/support -pthread $(EXTRA_CFLAGS)
CXXFLAGS := -std=c++17 -Wall -Wextra -Werror $(OPT) -Icommon -Iserver -pthread $(EXTRA_CFLAGS)
LDFLAGS  := $(OPT) -pthread
GL_LIBS  := $(shell pkg-config --libs glfw3 epoxy libpng 2>/dev/null || echo -lglfw -lepoxy -lpng16)
LIBS     := -lembree3 -lOpenMeshTools -lOpenMeshCore -levent -ljansson $(GL_LIBS) -lz -lm

ROLES      := common protocol server client client/view server/study
LIB_common   := $(BUILD)/libmscommon.a
LIB_protocol := $(BUILD)/libmsprotocol.a
LIB_server   := $(BUILD)/libmsserver.a
LIB_client   := $(BUILD)/libmsclient.a
LIB_client/view := $(BUILD)/libmsview.a
LIB_server/study := $(BUILD)/libmsstudy.a
# Link order: higher layers first.
ALL_LIBS   := $(LIB_server/study) $(LIB_server) $(LIB_client/view) $(LIB_client) $(LIB_protocol) $(LIB_common)

lib_srcs  = $(filter-out %_main.c,$(wildcard $(1)/*.c))
lib_objs  = $(patsubst %.c,$(BUILD)/%.o,$(call lib_srcs,$(1))) $(patsubst %.cpp,$(BUILD)/%.o,$(wildcard $(1)/*.cpp))
MAINS     := $(wildcard $(addsuffix /*_main.c,$(ROLES)))
PROGRAMS  := $(patsubst %_main.c,$(BUILD)/bin/%,$(notdir $(MAINS)))
TEST_SRCS := $(wildcard tests/test_*.c)
TESTS     := $(patsubst tests/%.c,$(BUILD)/tests/%,$(TEST_SRCS))
TESTSUPPORT := $(patsubst %.c,$(BUILD)/%.o,$(wildcard tests/support/*.c))
HAVE_CXX  := $(strip $(foreach r,$(ROLES),$(wildcard $(r)/*.cpp)))
LINK      := $(if $(HAVE_CXX),$(CXX),$(CC))

.PHONY: all test bench demo fuzz clean programs tests deps screenshots study
.SECONDARY:
all: programs

programs: $(PROGRAMS)
tests: $(TESTS) $(PROGRAMS)

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/%.o: %.cpp
	@mkdir -p $(dir $@)
	$(CXX) $(CXXFLAGS) -MMD -MP -c $< -o $@

define role_lib
$(LIB_$(1)): $(call lib_objs,$(1))
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^ $$(if $$^,,$(BUILD)/empty.o)
endef
$(foreach r,$(ROLES),$(eval $(call role_lib,$(r))))

# The viewer's GLSL (client/view/shaders/*.glsl) is embedded into libmsview as C
# strings (declared in client/view/ms_render_shaders.h) by a generated source.
SHADER_SRCS := $(wildcard client/view/shaders/*.glsl)
SHADER_GEN  := $(BUILD)/gen/ms_render_shaders.c
$(SHADER_GEN): $(SHADER_SRCS) client/view/shaders/embed_shaders.py
	@mkdir -p $(dir $@)
	python3 client/view/shaders/embed_shaders.py $@ $(SHADER_SRCS)
$(BUILD)/gen/ms_render_shaders.o: $(SHADER_GEN)
	$(CC) $(CFLAGS) -MMD -MP -c $< -o $@
$(LIB_client/view): $(BUILD)/gen/ms_render_shaders.o

# An empty archive still needs one member for ar on some systems.
$(BUILD)/empty.o:
	@mkdir -p $(dir $@)
	echo 'typedef int ms_empty_translation_unit;' | $(CC) $(CFLAGS) -x c -c - -o $@
$(foreach r,$(ROLES),$(eval $(LIB_$(r)): | $(BUILD)/empty.o))

$(BUILD)/bin/%: $(BUILD)/common/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@
$(BUILD)/bin/%: $(BUILD)/server/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@
$(BUILD)/bin/%: $(BUILD)/client/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@
$(BUILD)/bin/%: $(BUILD)/client/view/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@
$(BUILD)/bin/%: $(BUILD)/server/study/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@
$(BUILD)/bin/%: $(BUILD)/protocol/%_main.o $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(ALL_LIBS) $(LIBS) -o $@

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(TESTSUPPORT) $(ALL_LIBS)
	@mkdir -p $(dir $@)
	$(LINK) $(LDFLAGS) $< $(TESTSUPPORT) $(ALL_LIBS) $(LIBS) -lcmocka -o $@

# The whole suite under ASan + UBSan. Tests run from the repository root and find
# the shared models through MESHSTREAM_MODELS (default ../shared/data/models).
test:
	@$(MAKE) --no-print-directory MODE=asan tests
	@MODE=asan scripts/run-tests

bench: programs
	@scripts/bench

# What accuracy costs: sweeps over the dragon and the demo model, docs/ACCURACY.md
# and docs/images/study-*.png (scripts/study; a few minutes; not in CI).
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

-include $(shell find build -name '*.d' 2>/dev/null)
