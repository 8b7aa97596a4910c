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
EMCC    ?= emcc
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
         common/archive protocol server/geometry server/apo server/study \
         server/bake server/serve client/core client/lib client/load client/view \
         client/web
USES_common/util     :=
USES_common/mesh     := common/util
USES_common/codec    := common/mesh
USES_common/apo      := common/util
USES_common/camera   := common/util
USES_common/archive  := common/codec common/camera
USES_protocol        := common/util
USES_server/geometry := common/mesh
USES_server/apo      := server/geometry common/apo common/archive
USES_server/bake     := server/apo server/study
USES_server/serve    := common/archive protocol
USES_server/study    := common/apo common/archive
USES_client/core     := common/archive protocol
USES_client/lib      := client/core
USES_client/load     := client/core
USES_client/view     := client/core common/apo
USES_client/web      := common/archive common/apo
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
# pkg-config runs while the Makefile is read, also for `make demo` and `make deps`
# on a machine that lacks the libraries: it stays silent there, and check-deps
# stops a real build with one line instead.
pkg_libs     = $(if $(filter embree3,$(1)),-lembree3) \
               $(if $(filter-out embree3,$(1)),$(shell pkg-config --libs $(filter-out embree3,$(1)) 2>/dev/null))
pkg_cflags   = $(if $(filter-out embree3,$(1)),$(shell pkg-config --cflags $(filter-out embree3,$(1)) 2>/dev/null))

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

.PHONY: all test check bench demo fuzz clean programs tests deps screenshots rooms room-flags study \
        check-deps models
.PHONY: client-lib man install uninstall
.SECONDARY:
all: programs

programs: $(PROGRAMS)
# the browser's module too where Emscripten is installed (tests/test_browser.c)
tests: $(TESTS) $(PROGRAMS) $(if $(shell command -v $(EMCC) 2>/dev/null),wasm)

# Every library pkg-config should know (cmocka too when tests are built), and
# Embree 3's header: one line naming what is missing, before any compiler error.
CHECK_PKGS := $(filter-out embree3,$(ALL_PKGS)) $(if $(filter test tests,$(MAKECMDGOALS)),cmocka)
check-deps:
	@missing=""; \
	for p in $(CHECK_PKGS); do pkg-config --exists $$p 2>/dev/null || missing="$$missing $$p"; done; \
	echo '#include <embree3/rtcore.h>' | $(CC) -E -x c - >/dev/null 2>&1 || missing="$$missing embree3"; \
	[ -z "$$missing" ] || { echo "meshstream: missing libraries:$$missing (install them with scripts/install-deps)" >&2; exit 1; }

$(BUILD)/%.o: %.c | check-deps
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(ROOM_CFLAGS) -MMD -MP -c $< -o $@

$(BUILD)/%.o: %.cpp | check-deps
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
# timed. Tests run from the repository root and find their models in tests/data
# and in the cache scripts/fetch-models fills (tests/data/README.md;
# MESHSTREAM_MODELS overrides both).
test:
	@scripts/fetch-models
	@$(MAKE) --no-print-directory MODE=asan tests
	@MODE=asan scripts/run-tests

# The real scanned test models, fetched once into the cache (scripts/fetch-models).
models:
	@scripts/fetch-models

# The unit tier alone, every core at once: no servers, no display, no fetched models.
UNIT_TESTS := $(patsubst %,build/asan/tests/%,$(shell awk '$$1 ~ /^test_/ && $$2 == "unit" {print $$1}' tests/tiers.txt))
check:
	@$(MAKE) --no-print-directory MODE=asan $(UNIT_TESTS)
	@MODE=asan TIERS=unit scripts/run-tests

bench: programs
	@scripts/fetch-models
	@scripts/bench

# What accuracy costs: sweeps over the dragon and the demo model, docs/ACCURACY.md
# and docs/images/study-*.png (scripts/study; 10 to 15 minutes; not in CI).
study: programs
	@scripts/fetch-models
	@scripts/study

# The viewer's pictures in docs/images/ (headless meshview; Xvfb when no DISPLAY).
screenshots: programs
	@scripts/fetch-models
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

# ---- Version, client library, man pages, install (docs/INSTALL.md) ----------
# One version: the VERSION file, compiled into ms_version.o alone (every
# program's --version and msc_version). The client library is the client/lib
# facade and the rooms it uses, compiled again as position-independent code
# with every symbol hidden but the facade's msc_* (meshstream-client.h), as a
# shared object (soname libmeshstream-client.so.CLIENT_ABI) and a static archive.
VERSION      := $(shell cat VERSION)
CLIENT_ABI   := 0
PREFIX       ?= /usr/local
BINDIR       ?= $(PREFIX)/bin
LIBDIR       ?= $(PREFIX)/lib
INCLUDEDIR   ?= $(PREFIX)/include
MANDIR       ?= $(PREFIX)/share/man
DATADIR      ?= $(PREFIX)/share/meshstream
DOCDIR       ?= $(PREFIX)/share/doc/meshstream
UNITDIR      ?= $(PREFIX)/lib/systemd/system
PKGCONFIGDIR ?= $(LIBDIR)/pkgconfig
PIC          := $(BUILD)/pic
CLIENT_ROOMS := $(call reverse,$(filter $(call room_closure,client/lib),$(ROOMS)))
CLIENT_PKGS  := $(call room_pkgs,client/lib)
CLIENT_SO    := libmeshstream-client.so.$(CLIENT_ABI)
CLIENT_LIBS  := $(BUILD)/lib/libmeshstream-client.so.$(VERSION) $(BUILD)/lib/libmeshstream-client.a
pic_lib       = $(PIC)/lib/libms_$(subst /,_,$(1)).a
MAN_PAGES    := $(patsubst $(BUILD)/bin/%,$(BUILD)/man/%.1,$(PROGRAMS))
$(BUILD)/common/util/ms_version.o $(PIC)/common/util/ms_version.o: CFLAGS += -DMS_VERSION='"$(VERSION)"'
$(BUILD)/common/util/ms_version.o $(PIC)/common/util/ms_version.o: VERSION
define pic_rules
$(PIC)/$(1)/%.o: $(1)/%.c
	@mkdir -p $$(dir $$@)
	$$(CC) $$(CFLAGS) -fPIC -fvisibility=hidden $(addprefix -I,$(call room_closure,$(1))) $(call pkg_cflags,$(call room_pkgs,$(1))) -MMD -MP -c $$< -o $$@
$(call pic_lib,$(1)): $(patsubst %.c,$(PIC)/%.o,$(call lib_srcs,$(1)))
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach r,$(CLIENT_ROOMS),$(eval $(call pic_rules,$(r))))
client-lib: $(CLIENT_LIBS)
# Linking the archives (not every object) keeps only what the facade reaches.
$(BUILD)/lib/libmeshstream-client.so.$(VERSION): $(foreach r,$(CLIENT_ROOMS),$(call pic_lib,$(r)))
	$(CC) -shared $(LDFLAGS) -Wl,-soname,$(CLIENT_SO) -Wl,--no-undefined -Wl,--whole-archive $< \
	  -Wl,--no-whole-archive $(wordlist 2,99,$^) $(call pkg_libs,$(CLIENT_PKGS)) -lm -o $@
$(BUILD)/lib/libmeshstream-client.a: $(foreach r,$(CLIENT_ROOMS),$(patsubst %.c,$(PIC)/%.o,$(call lib_srcs,$(r))))
	rm -f $@ && ar rcs $@ $^
# Man pages from each program's --help and --version; the NAME line is the
# program's README heading ("### meshgen — the built-in demo model"; one may
# name several programs).
man: $(MAN_PAGES)
$(BUILD)/man/%.1: $(BUILD)/bin/% README.md VERSION
	@mkdir -p $(dir $@)
	@command -v help2man >/dev/null || { echo "man: help2man is missing (scripts/install-deps)" >&2; exit 1; }
	help2man --no-info --no-discard-stderr --name="$$(awk -F ' — ' '/^### /{sub(/^### /,"",$$1); gsub(/,/,"",$$1); n=split($$1,w," "); for(i=1;i<=n;i++) if(w[i]=="$*") print $$2}' README.md)" --output=$@ $<
INSTALLED = $(addprefix $(BINDIR)/,$(notdir $(PROGRAMS))) $(addprefix $(MANDIR)/man1/,$(notdir $(MAN_PAGES))) \
  $(LIBDIR)/libmeshstream-client.so.$(VERSION) $(LIBDIR)/$(CLIENT_SO) $(LIBDIR)/libmeshstream-client.so \
  $(LIBDIR)/libmeshstream-client.a $(INCLUDEDIR)/meshstream-client.h $(PKGCONFIGDIR)/meshstream-client.pc \
  $(UNITDIR)/meshserve@.service $(addprefix $(DATADIR)/deploy/,$(filter-out meshserve@.service,$(notdir $(wildcard deploy/*)))) \
  $(addprefix $(DOCDIR)/,README.md LICENSE $(notdir $(wildcard docs/*.md))) $(DOCDIR)/examples/client_example.c
install: programs client-lib man
	install -d $(addprefix $(DESTDIR),$(BINDIR) $(MANDIR)/man1 $(LIBDIR) $(INCLUDEDIR) $(PKGCONFIGDIR) $(UNITDIR) $(DATADIR)/deploy $(DOCDIR)/examples)
	install -m 755 $(PROGRAMS) $(DESTDIR)$(BINDIR)/
	install -m 644 $(MAN_PAGES) $(DESTDIR)$(MANDIR)/man1/
	install -m 755 $(BUILD)/lib/libmeshstream-client.so.$(VERSION) $(DESTDIR)$(LIBDIR)/
	ln -sf libmeshstream-client.so.$(VERSION) $(DESTDIR)$(LIBDIR)/$(CLIENT_SO)
	ln -sf $(CLIENT_SO) $(DESTDIR)$(LIBDIR)/libmeshstream-client.so
	install -m 644 $(BUILD)/lib/libmeshstream-client.a $(DESTDIR)$(LIBDIR)/
	install -m 644 client/lib/meshstream-client.h $(DESTDIR)$(INCLUDEDIR)/
	sed -e 's|@PREFIX@|$(PREFIX)|; s|@LIBDIR@|$(LIBDIR)|; s|@INCLUDEDIR@|$(INCLUDEDIR)|' \
	  -e 's|@VERSION@|$(VERSION)|; s|@REQUIRES@|$(CLIENT_PKGS)|' client/lib/meshstream-client.pc.in \
	  > $(DESTDIR)$(PKGCONFIGDIR)/meshstream-client.pc
	sed 's|/usr/local|$(PREFIX)|g' deploy/meshserve@.service > $(DESTDIR)$(UNITDIR)/meshserve@.service
	install -m 644 $(filter-out deploy/meshserve@.service deploy/fill,$(wildcard deploy/*)) $(DESTDIR)$(DATADIR)/deploy/
	install -m 755 deploy/fill $(DESTDIR)$(DATADIR)/deploy/
	install -m 644 README.md $(wildcard LICENSE) docs/*.md $(DESTDIR)$(DOCDIR)/
	install -m 644 examples/client_example.c $(DESTDIR)$(DOCDIR)/examples/
uninstall:
	rm -f $(addprefix $(DESTDIR),$(INSTALLED))
	-rmdir $(addprefix $(DESTDIR),$(DOCDIR)/examples $(DOCDIR) $(DATADIR)/deploy $(DATADIR)) 2>/dev/null

# ---- The browser client (docs/BROWSER.md) -----------------------------------
# `make wasm`: the decoding sources compiled to WebAssembly by Emscripten
# (Debian's emscripten; its Node needs NODE_PATH) with the page of web/, into
# build/wasm/site, the folder meshserve --web-dir serves. Only what the view
# decoder needs: no JSON, PNG or gzip input; zlib's CRC-32 and inflate from
# web/wasm (its inflate: client/web/ms_web_inflate.c).
comma       := ,
space       := $(subst ,, )
WASM        := build/wasm
WASM_ROOMS  := common/util common/mesh common/codec common/apo common/camera common/archive client/web
WASM_SKIP   := common/util/ms_byte_source.c common/util/ms_json_out.c common/util/ms_png.c \
               common/util/ms_version.c common/util/ms_input_file.c \
               common/util/ms_cli.c common/util/ms_process_memory.c common/archive/ms_catalog.c \
               common/archive/ms_catalog_text.c common/archive/ms_metadata.c \
               common/archive/ms_annotations.c common/apo/ms_apo_blob.c common/apo/ms_apo_stream.c
WASM_SRCS   := $(filter-out $(WASM_SKIP),$(foreach r,$(WASM_ROOMS),$(call lib_srcs,$(r)))) \
               web/wasm/ms_wasm_zlib.c
WASM_OBJS   := $(patsubst %.c,$(WASM)/obj/%.o,$(WASM_SRCS))
WASM_CFLAGS := $(CSTD) $(WARN) -O2 -DNDEBUG -Iweb/wasm/include $(addprefix -I,$(WASM_ROOMS))
WASM_EXPORTS := malloc free ms_web_view_new ms_web_view_free ms_web_view_error ms_web_view_box \
               ms_web_view_budget ms_web_view_forgotten_cells ms_web_view_forgotten_bytes \
               ms_web_view_cell_count ms_web_view_bounds ms_web_view_camera ms_web_view_culled ms_web_view_permit ms_web_view_plan \
               ms_web_view_plan_count ms_web_view_plan_cell ms_web_view_plan_bits \
               ms_web_view_plan_bytes ms_web_view_held ms_web_view_give ms_web_view_stitch \
               ms_web_view_vertex_count ms_web_view_triangle_count ms_web_view_positions ms_web_view_normals \
               ms_web_view_triangles ms_web_view_shown_cells ms_web_view_max_bits ms_web_view_bytes_held \
               ms_web_view_sections ms_web_view_cast ms_web_view_threads ms_web_view_plan_ahead \
               ms_web_view_new_head ms_web_view_give_subtree ms_web_view_plan_subtree_count \
               ms_web_view_plan_subtree ms_web_view_subtrees_held ms_web_view_index_bytes_held \
               ms_web_view_prefix ms_web_view_has_colour ms_web_view_plan_colour_count \
               ms_web_view_plan_colour_cell ms_web_view_plan_colour_bits ms_web_view_plan_colour_bytes \
               ms_web_view_colour_prefix ms_web_view_colour_held ms_web_view_give_colour ms_web_view_colours \
               ms_web_view_run_count ms_web_view_run_cells ms_web_view_run_firsts ms_web_view_cell_cube \
               ms_web_apo_new ms_web_apo_free ms_web_apo_geometry ms_web_apo_plan ms_web_apo_plan_cell ms_web_apo_plan_levels \
               ms_web_apo_plan_bytes ms_web_apo_held ms_web_apo_level_texels ms_web_apo_give
WASM_LDFLAGS := -O2 -sMODULARIZE=1 -sEXPORT_NAME=createMeshstream -sENVIRONMENT=worker \
               -sALLOW_MEMORY_GROWTH=1 -sFILESYSTEM=0 -sEXIT_RUNTIME=0 \
               -sEXPORTED_RUNTIME_METHODS=[HEAPU8,HEAPU32,HEAPF32,HEAPF64,UTF8ToString] \
               -sEXPORTED_FUNCTIONS=[$(subst $(space),$(comma),$(strip $(addprefix _,$(WASM_EXPORTS))))]
# The same module with pthreads (meshstream-mt: decoding on several threads,
# ms_web_view_threads; no pool made in advance: the worker makes its helpers
# after the first picture), which a cross-origin isolated page loads (meshserve
# sends COOP and COEP); its objects are built apart, with -pthread. The
# helper threads' script is renamed meshstream-mt-worker.js (a page file's
# name has one dot); the loader finds it through the worker's locateFile.
WASM_MT_OBJS := $(patsubst %.c,$(WASM)/obj-mt/%.o,$(WASM_SRCS))
WASM_MT_LDFLAGS := $(subst createMeshstream,createMeshstreamThreads,$(WASM_LDFLAGS)) -pthread \
               -Wno-pthreads-mem-growth \
               -sEXPORTED_RUNTIME_METHODS=[HEAPU8,HEAPU32,HEAPF32,HEAPF64,UTF8ToString,wasmMemory]
WEB_FILES   := $(wildcard web/*.html web/*.js web/*.css)
# Draco's own WebAssembly decoder (npm draco3d, which scripts/install-deps puts
# in a cache outside the repository) for the Draco page, web/draco.html: copied
# beside the pages when there, a note when not (the page then says so).
DRACO3D     ?= $(or $(MESHSTREAM_DRACO3D),$(or $(XDG_CACHE_HOME),$(HOME)/.cache)/meshstream/draco3d)
DRACO3D_FILES := draco_decoder_nodejs.js draco_decoder.wasm
.PHONY: wasm
wasm: $(WASM)/site/meshstream.js $(WASM)/site/meshstream-mt.js $(patsubst web/%,$(WASM)/site/%,$(WEB_FILES)) \
      $(WASM)/site/shaders.js $(WASM)/site/viewer.js
	@if [ -s "$(DRACO3D)/draco_decoder_nodejs.js" ] && [ -s "$(DRACO3D)/draco_decoder.wasm" ]; then \
	  for f in $(DRACO3D_FILES); do cmp -s "$(DRACO3D)/$$f" $(WASM)/site/$$f || cp "$(DRACO3D)/$$f" $(WASM)/site/$$f; done; \
	else \
	  rm -f $(addprefix $(WASM)/site/,$(DRACO3D_FILES)); \
	  echo "wasm: no Draco decoder in $(DRACO3D) (npm draco3d: scripts/install-deps); the Draco page will say so"; \
	fi
$(WASM)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	@command -v $(EMCC) >/dev/null || { echo "wasm: emcc is missing (scripts/install-deps)" >&2; exit 1; }
	NODE_PATH=/usr/share/nodejs $(EMCC) $(WASM_CFLAGS) -MMD -MP -c $< -o $@
$(WASM)/site/meshstream.js: $(WASM_OBJS)
	@mkdir -p $(dir $@)
	NODE_PATH=/usr/share/nodejs $(EMCC) $(WASM_LDFLAGS) $^ -o $@
$(WASM)/obj-mt/%.o: %.c
	@mkdir -p $(dir $@)
	@command -v $(EMCC) >/dev/null || { echo "wasm: emcc is missing (scripts/install-deps)" >&2; exit 1; }
	NODE_PATH=/usr/share/nodejs $(EMCC) $(WASM_CFLAGS) -pthread -MMD -MP -c $< -o $@
$(WASM)/site/meshstream-mt.js: $(WASM_MT_OBJS)
	@mkdir -p $(dir $@)
	NODE_PATH=/usr/share/nodejs $(EMCC) $(WASM_MT_LDFLAGS) $^ -o $@
	mv $(WASM)/site/meshstream-mt.worker.js $(WASM)/site/meshstream-mt-worker.js
# The page's shaders: meshview's, in GLSL ES 3.00 (web/es_shaders.py; docs/BROWSER.md "Drawing").
$(WASM)/site/shaders.js: client/view/shaders/cell.vert.glsl client/view/shaders/cell.frag.glsl \
                         client/view/shaders/apo.glsl web/es_shaders.py
	@mkdir -p $(dir $@)
	python3 web/es_shaders.py $@ client/view/shaders
$(WASM)/site/%: web/%
	@mkdir -p $(dir $@)
	cp $< $@
# The viewer page's scripts after boot.js, in view.html's order, as the one
# file it loads: one request where there were ten (a browser opens at most
# six connections to a server, so the rest waited a round trip or two behind
# them, and the worker's script and the model's first requests behind those;
# docs/BROWSER.md, "First pixels").
VIEWER_JS   := web/share.js web/light.js web/section.js web/measure.js web/tools.js $(WASM)/site/shaders.js \
               web/camera.js web/render.js web/view.js web/annotations.js
$(WASM)/site/viewer.js: $(VIEWER_JS)
	@mkdir -p $(dir $@)
	cat $^ > $@
# The decoding worker's script with both modules' loaders after it (it takes
# the one the page can run): its loader no longer a request of its own, one
# round trip after the worker's start (docs/BROWSER.md, "First pixels").
# The helper threads still read meshstream-mt.js itself.
$(WASM)/site/worker.js: web/worker.js $(WASM)/site/meshstream-mt.js $(WASM)/site/meshstream.js
	@mkdir -p $(dir $@)
	cat $^ > $@

# The layering, for tests/test_layering.c and for reading: `make -s rooms`, and
# `make -s room-flags ROOM=client/view` (the include paths that room compiles with).
rooms:
	@echo $(ROOMS)
room-flags:
	@echo $(addprefix -I,$(call room_closure,$(ROOM)))

-include $(shell find build -name '*.d' 2>/dev/null)
