/* The friction feed-forward of joint j1 from the header `frictid export params.yaml --to c -o friction.h`
   writes (docs/using-the-model.md). Build: gcc -std=c99 -O2 -I. -o ff docs/examples/ff.c -lm */
#include <stdio.h>
#include "friction.h"

int main(void) {
    for (double w = -1.0; w <= 1.0; w += 0.5)
        printf("w %5.2f rad/s: friction %8.4f N m\n", w, j1_friction(w, 25.0));
    return 0;
}
