# libFuzzer targets (clang only; not part of CI): `make fuzz` builds every
# tests/fuzz/fuzz_*.c into build/fuzz/fuzz_NAME, linked with the common library
# sources compiled with -fsanitize=fuzzer-no-link,address,undefined.
# Run: build/fuzz/fuzz_codec_decode -max_total_time=600 build/fuzz/corpus-codec tests/corpus/codec
FUZZ_CC    ?= clang
FUZZ_BUILD := build/fuzz
FUZZ_FLAGS := -std=c11 -D_DEFAULT_SOURCE -D_FILE_OFFSET_BITS=64 -g -O1 -Icommon \
              -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
FUZZ_LIB_SRCS := $(filter-out %_main.c,$(wildcard common/*.c))
FUZZ_LIB_OBJS := $(patsubst %.c,$(FUZZ_BUILD)/%.o,$(FUZZ_LIB_SRCS))
FUZZ_TARGETS  := $(patsubst tests/fuzz/%.c,$(FUZZ_BUILD)/%,$(wildcard tests/fuzz/fuzz_*.c))

all: $(FUZZ_TARGETS)

$(FUZZ_BUILD)/common/%.o: common/%.c
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_FLAGS) -fsanitize=fuzzer-no-link -c $< -o $@

$(FUZZ_BUILD)/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_LIB_OBJS)
	@mkdir -p $(dir $@)
	$(FUZZ_CC) $(FUZZ_FLAGS) -fsanitize=fuzzer $< $(FUZZ_LIB_OBJS) -levent -ljansson -lz -lm -pthread -o $@

.PHONY: all
.SECONDARY:
