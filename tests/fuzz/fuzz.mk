# libFuzzer targets, called by `make fuzz` as `$(MAKE) -f tests/fuzz/fuzz.mk`.
#
# Generic: every tests/fuzz/fuzz_NAME.c becomes build/fuzz/fuzz_NAME, linked with
# every library source of the common/ rooms and protocol/ (not *_main.c), all compiled by
# clang with -fsanitize=fuzzer-no-link,address,undefined. Each target is then
# run for FUZZ_TIME seconds, seeded from tests/corpus/NAME/ (read only; new
# inputs go to build/fuzz/corpus/NAME/), and the run fails on the first crash.
#
#   make fuzz                              build and run every target, 600 s each
#   make fuzz FUZZ_TIME=60 FUZZ_TARGETS=protocol
#   make -f tests/fuzz/fuzz.mk build       build only
#   make -f tests/fuzz/fuzz.mk merge       fold new finds into tests/corpus/NAME/

CLANG        ?= clang
FUZZ_TIME    ?= 600
FUZZ_FLAGS   ?=
FUZZ_DIR     := build/fuzz
FUZZ_SRCS    := $(wildcard tests/fuzz/fuzz_*.c)
FUZZ_ALL     := $(patsubst tests/fuzz/fuzz_%.c,%,$(FUZZ_SRCS))
FUZZ_TARGETS ?= $(FUZZ_ALL)
FUZZ_BINS    := $(patsubst %,$(FUZZ_DIR)/fuzz_%,$(FUZZ_TARGETS))

# From server/serve/: the side door's header parsing (fuzz_http_request) and the
# config reader (fuzz_config_catalog); from client/web/: the browser build's own
# inflater (fuzz_web_inflate, against zlib).
LIB_SRCS   := $(filter-out %_main.c,$(wildcard common/*/*.c protocol/*.c)) \
              server/serve/ms_http_parse.c server/serve/ms_server_config.c \
              server/serve/ms_http_cors.c client/web/ms_web_inflate.c
LIB_OBJS   := $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(LIB_SRCS))
SAN        := -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZ_CFLAGS := -std=c11 -D_DEFAULT_SOURCE -D_FILE_OFFSET_BITS=64 -O1 -g \
               -fno-omit-frame-pointer $(SAN) -fsanitize=fuzzer-no-link \
               -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wvla \
               $(addprefix -I,$(wildcard common/*) protocol server/serve client/web tests/support) -pthread
FUZZ_LIBS  := $(shell pkg-config --libs jansson libevent libpng zlib) -lm -pthread
# the one version of the project, as the main Makefile gives it
$(FUZZ_DIR)/obj/common/util/ms_version.o: FUZZ_CFLAGS += -DMS_VERSION='"$(shell cat VERSION)"'

.PHONY: all build run merge clean
.SECONDARY:

all: run

build: $(FUZZ_BINS)

$(FUZZ_DIR)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CLANG) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/fuzz_%: $(FUZZ_DIR)/obj/tests/fuzz/fuzz_%.o $(LIB_OBJS)
	$(CLANG) $(SAN) -fsanitize=fuzzer $^ $(FUZZ_LIBS) -o $@

run: $(FUZZ_BINS)
	@set -e; for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_DIR)/corpus/$$t tests/corpus/$$t; \
	  echo "fuzz: fuzz_$$t for $(FUZZ_TIME) s, seeded from tests/corpus/$$t"; \
	  $(FUZZ_DIR)/fuzz_$$t -max_total_time=$(FUZZ_TIME) -print_final_stats=1 \
	    -artifact_prefix=$(FUZZ_DIR)/fuzz_$$t- $(FUZZ_FLAGS) \
	    $(FUZZ_DIR)/corpus/$$t tests/corpus/$$t; \
	done

merge: $(FUZZ_BINS)
	@set -e; for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_DIR)/corpus/$$t tests/corpus/$$t; \
	  $(FUZZ_DIR)/fuzz_$$t -merge=1 tests/corpus/$$t $(FUZZ_DIR)/corpus/$$t; \
	done

clean:
	rm -rf $(FUZZ_DIR)

-include $(shell find $(FUZZ_DIR)/obj -name '*.d' 2>/dev/null)
